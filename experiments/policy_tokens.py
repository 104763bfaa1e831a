"""`python experiments/policy_tokens.py [--<field>=<value> ...]` (see `--help`)."""

from lerobot_unidextok.experiments.policy_tokens import main

if __name__ == "__main__":
    main()
