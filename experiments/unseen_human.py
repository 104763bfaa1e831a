"""`python experiments/unseen_human.py [--<field>=<value> ...]` (see `--help`)."""

from lerobot_unidextok.experiments.unseen_human import main

if __name__ == "__main__":
    main()
