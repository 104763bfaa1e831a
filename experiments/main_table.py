"""`python experiments/main_table.py [--config_path=configs/experiments/<default|tiny|longer>.yaml] [--data=auto|real|sample] [--datasets='[a,b]'] [--<field>=<value>]`"""

from lerobot_unidextok.experiments.main_table import main

if __name__ == "__main__":
    main()
