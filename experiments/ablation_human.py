"""`python experiments/ablation_human.py [--config_path=configs/experiments/<default|tiny|longer>.yaml] [--data=auto|real|sample] [--datasets='[a,b]'] [--<field>=<value>]`"""

from lerobot_unidextok.experiments.ablation_human import main

if __name__ == "__main__":
    main()
