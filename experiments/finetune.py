"""`python experiments/finetune.py [--<field>=<value> ...]` (see `--help`)."""

from lerobot_unidextok.experiments.finetune import main

if __name__ == "__main__":
    main()
