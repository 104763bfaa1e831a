"""LeRobot's plugin entry for lerobot-unidextok (the code lives in `lerobot_unidextok`).

LeRobot's CLIs (lerobot-train, -eval, -record, -replay, -rollout, ...) call
`lerobot.utils.import_utils.register_third_party_plugins()` at start, which imports every installed
distribution whose name starts with `lerobot_policy_` under that name: this package. Importing it
registers the `<type>_udt` policy types (`act_udt`, `diffusion_udt`, `vqbet_udt`), the `unidextok.*`
processor steps and the simulator's `--env.type=unidextok` (`lerobot_env_unidextok`, registered without
importing MuJoCo), so no `--policy.discover_packages_path` or `--env.discover_packages_path` flag is needed. As the start of a LeRobot CLI it
also turns LeRobot's torchcodec/FFmpeg warning (a wall of tracebacks) into a one-line note, and a mistake this
package reports (a `UserError`, e.g. a `<type>_udt` policy on a dataset that was never converted) into one
`error:` line and exit status 2, as this package's own tools end (`utils/cli.py`), and so a few of LeRobot's
own errors whose fix is known (`lerobot_errors.py`: a `_udt` policy on a v2.1 dataset, no eval episodes).

In Python, `import lerobot_policy_unidextok` before LeRobot's factories (`make_policy`,
`PreTrainedConfig.from_pretrained`, `PolicyProcessorPipeline.from_pretrained`), which never discover plugins.
"""

from lerobot_policy_unidextok.lerobot_errors import user_error_for
from lerobot_unidextok.utils.cli import quiet_torchcodec_warning, user_errors_in_lerobot_clis

quiet_torchcodec_warning()
user_errors_in_lerobot_clis(user_error_for)  # also LeRobot's own errors with a fix we know (lerobot_errors.py)

import lerobot_env_unidextok.configuration  # noqa: E402, F401  (registration on import: --env.type=unidextok)
from lerobot_unidextok import policies, processor  # noqa: E402  (registration on import)
from lerobot_unidextok.policies import UDT_CONFIGS  # noqa: E402

__all__ = ["UDT_CONFIGS", "policies", "processor"]
