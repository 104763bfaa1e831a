"""`python experiments/eval_policy.py --checkpoint=<pretrained_model> --dataset=<converted root> [--episodes='[...]']`"""

from lerobot_unidextok.experiments.policy_checkpoint import main

if __name__ == "__main__":
    main()
