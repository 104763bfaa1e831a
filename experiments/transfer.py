"""`python experiments/transfer.py [--config_path=configs/experiments/<default|tiny|longer>.yaml] [--data=auto|real|sample] [--datasets='[a,b]'] [--<field>=<value>]`"""

from lerobot_unidextok.experiments.transfer import main

if __name__ == "__main__":
    main()
