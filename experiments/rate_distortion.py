"""`python experiments/rate_distortion.py [--<field>=<value> ...]` (see `--help`)."""

from lerobot_unidextok.experiments.rate_distortion import main

if __name__ == "__main__":
    main()
