"""`python experiments/error_split.py [--<field>=<value> ...]` (see `--help`)."""

from lerobot_unidextok.experiments.error_split import main

if __name__ == "__main__":
    main()
