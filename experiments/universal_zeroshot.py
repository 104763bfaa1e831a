"""`python experiments/universal_zeroshot.py [--<field>=<value> ...]` (see `--help`)."""

from lerobot_unidextok.experiments.universal_zeroshot import main

if __name__ == "__main__":
    main()
