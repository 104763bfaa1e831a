"""`python experiments/ablation_mapping.py [--tiny] [--datasets=a,b] [--config_path=configs/experiments/default.yaml] [--<field>=<value>]`"""

from lerobot_unidextok.experiments.ablation_mapping import main

if __name__ == "__main__":
    main()
