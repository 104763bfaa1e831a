"""`python experiments/main_table.py [--tiny] [--datasets=a,b] [--config_path=configs/experiments/default.yaml] [--<field>=<value>]`"""

from lerobot_unidextok.experiments.main_table import main

if __name__ == "__main__":
    main()
