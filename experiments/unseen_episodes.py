"""`python experiments/unseen_episodes.py [--<field>=<value> ...]` (see `--help`)."""

from lerobot_unidextok.experiments.unseen_episodes import main

if __name__ == "__main__":
    main()
