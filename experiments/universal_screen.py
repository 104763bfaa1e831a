"""`python experiments/universal_screen.py [--<field>=<value> ...]` (see `--help`)."""

from lerobot_unidextok.experiments.universal_screen import main

if __name__ == "__main__":
    main()
