"""`python experiments/make_results.py [--results_dir=outputs/experiments] [--page=benchmarks/RESULTS.md]` (draccus flags)"""

from lerobot_unidextok.experiments.results_page import main

if __name__ == "__main__":
    main()
