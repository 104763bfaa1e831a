"""`python experiments/probe.py [--tiny] [--datasets=a,b] [--config_path=configs/experiments/default.yaml] [--<field>=<value>]`"""

from lerobot_unidextok.experiments.probe import main

if __name__ == "__main__":
    main()
