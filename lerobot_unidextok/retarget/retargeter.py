"""Human MANO-21 keypoint motion -> robot joint trajectories of a registered hand, with dex-retargeting.

The field's standard, `dex-retargeting` (dexsuite/dex-retargeting, `retargeting_config.py`,
`optimizer.py::VectorOptimizer`, `seq_retarget.py`), is used as it is: a `RetargetingConfig` of type
"vector" built on the robot's URDF, solved frame after frame with SLSQP (nlopt), warm-started from the
previous frame. Our part is the glue, all data-driven from the hand's spec (`hands/specs/<hand>.yaml`, read
through `retarget/spec.py`):

1. Frames. Each keypoint frame is expressed in its own palm frame (wrist, index / middle / pinky MCP), and the
   robot's palm frame is read from its URDF at the zero pose (wrist link and MCP links), so human keypoints
   in any frame (camera, MANO wrist frame, UDHM's canonical frame) map onto the robot's base frame. This
   replaces dex-retargeting's hand-tuned `OPERATOR2MANO` matrices, which fit only URDFs already aligned to MANO.
2. Scale. `scaling` defaults to robot reach / human reach (wrist -> middle-finger target, robot at its zero
   pose vs the default UDHM human skeleton flat), in place of the configs' hand-tuned `scaling_factor`.
3. Units. The optimised URDF angles become the hand's native values (the spec's own map from radians to raw
   values, or `raw_at_urdf_limits` where the URDF's angles are not the spec's radians), then UDHM with `hands.get(hand).to_udhm(native, side)`: the hand spec
   decides slots and signs, nothing is repeated here.

Needs the `retarget` extra (`pip install 'lerobot_policy_unidextok[retarget]'`), imported when a retargeter is built.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import contextlib
import logging
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_unidextok.constants import KEYPOINT_NAMES, NUM_KEYPOINTS, UDHM_DIM
from lerobot_unidextok.hands.urdf import URDFError, find_urdfs, flatten_mimic_chains, link_names, read_joints
from lerobot_unidextok.retarget.spec import PALM_KEYS, JointLink, SideRetargetSpec, get_retarget_spec
from lerobot_unidextok.utils.cli import progress_bar
from lerobot_unidextok.utils.imports import require_package

logger = logging.getLogger(__name__)

_PALM_KEYPOINTS = {"wrist": 0, "index_mcp": 5, "middle_mcp": 9, "pinky_mcp": 17}


def require_dex_retargeting() -> None:
    """ImportError naming the `retarget` extra when dex-retargeting (or its pinocchio / nlopt) is missing."""
    require_package(
        "dex-retargeting", "retarget", purpose="retargeting", import_name="dex_retargeting",
        hint=" (Python < 3.13; it brings pinocchio `pin` and nlopt)",
    )  # fmt: skip


@dataclass(frozen=True)
class RetargetConfig:
    """Settings of dex-retargeting's vector optimizer (defaults = its `RetargetingConfig` defaults)."""

    scaling: float | None = None  # robot / human size; None = measured reach ratio (module docstring, step 2)
    low_pass_alpha: float = 1.0  # dex-retargeting's low-pass filter; 1 = none (offline data keep their timing)
    huber_delta: float = 2e-2  # m, dex-retargeting default
    normal_delta: float = 4e-3  # dex-retargeting default (regularises towards the previous frame)
    progress: bool = False

    def __post_init__(self) -> None:
        if self.scaling is not None and self.scaling <= 0:
            raise ValueError(f"scaling must be > 0 or None (measured), got {self.scaling}")
        if not 0.0 < self.low_pass_alpha <= 1.0:
            raise ValueError(f"low_pass_alpha must be in (0, 1], got {self.low_pass_alpha}")


@dataclass
class RetargetResult:
    """One retargeted sequence of T frames."""

    hand: str
    side: str
    urdf_joint_names: list[str]  # the spec's URDF joints, in the spec's native-joint order
    urdf_qpos_rad: np.ndarray  # (T, J) URDF joint angles
    native: np.ndarray  # (T, num_native) the hand's native units (hand spec)
    udhm_rad: np.ndarray  # (T, 22) hands.get(hand).to_udhm(native, side)
    target_error_mm: np.ndarray  # (T, K) |robot - scaled human| wrist -> target vectors
    scaling: float

    @property
    def mean_target_error_mm(self) -> float:
        return float(self.target_error_mm.mean())


def palm_frame(wrist: np.ndarray, index_mcp: np.ndarray, middle_mcp: np.ndarray, pinky_mcp: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation whose columns are the palm axes: x palm normal, y across the palm, z wrist -> middle MCP.

    The normal is cross(index - wrist, pinky - wrist): the same formula on a human and a robot hand of the
    same side gives frames that agree, whatever the chirality convention.
    """
    z = middle_mcp - wrist
    z = z / np.linalg.norm(z, axis=-1, keepdims=True).clip(1e-9)
    n = np.cross(index_mcp - wrist, pinky_mcp - wrist)
    x = n - (n * z).sum(-1, keepdims=True) * z
    x = x / np.linalg.norm(x, axis=-1, keepdims=True).clip(1e-9)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)  # (..., 3, 3), columns x, y, z


@contextlib.contextmanager
def _temp_root(folder: str):
    """dex-retargeting's `build()` writes a URDF copy with `tempfile.mkdtemp`; keep it inside `folder`."""
    saved = tempfile.tempdir
    tempfile.tempdir = folder
    try:
        yield
    finally:
        tempfile.tempdir = saved


class HandRetargeter:
    """Retarget MANO-21 keypoint sequences of one side onto one registered robot hand."""

    def __init__(self, hand: str, urdf: str | Path, side: str = "right", config: RetargetConfig | None = None) -> None:
        from lerobot_unidextok import hands

        require_dex_retargeting()
        self.hand, self.side = hand, side
        self.config = config or RetargetConfig()
        self.hand_spec = hands.get(hand)
        if self.hand_spec.kind != "joints":
            raise ValueError(f"hand {hand!r} is given as keypoints; retarget onto a robot hand with joints")
        self.spec: SideRetargetSpec = get_retarget_spec(hand, side)
        errors = []
        for path in find_urdfs(urdf, self.spec.urdf):  # several files may share the name: take one that fits
            try:
                self._check_spec(path)
                self.urdf_path = path
                break
            except URDFError as e:
                errors.append(str(e))
        else:
            raise URDFError("; ".join(errors))
        self._build()

    # -----------------------------------------------------------------------------------------
    def _check_spec(self, path: Path) -> None:
        joints = read_joints(path)
        links = link_names(path)
        where = f"{path} (hand spec {self.hand}, {self.side})"
        slots = {j.name: j.sides[self.side].slot for j in self.hand_spec.joints}
        driven: list[JointLink] = []
        for j in self.spec.joints:
            if j.urdf not in joints or joints[j.urdf].type not in ("revolute", "prismatic", "continuous"):
                if slots[j.native] is None:
                    continue  # a reserved channel the URDF does not have: it keeps its spec default
                raise URDFError(f"{where}: no movable joint {j.urdf!r} for native joint {j.native!r}; movable joints: "
                                f"{sorted(n for n, x in joints.items() if x.type != 'fixed')}")  # fmt: skip
            if joints[j.urdf].mimic is not None:
                raise URDFError(f"{where}: joint {j.urdf!r} mimics {joints[j.urdf].mimic[0]!r}; give native joint "
                                f"{j.native!r} the `urdf_joint` it follows")  # fmt: skip
            driven.append(j)
        self.driven: tuple[JointLink, ...] = tuple(driven)
        wanted = [self.spec.wrist_link, *self.spec.palm_links.values(), *self.spec.target_links]
        missing = [name for name in wanted if name not in links]
        if missing:
            raise URDFError(f"{where}: links {missing} not in the URDF; its links: {sorted(links)}")
        self._urdf_joints = joints

    def _build(self) -> None:
        from dex_retargeting.retargeting_config import RetargetingConfig

        spec, cfg = self.spec, self.config
        k = len(spec.target_links)
        self.urdf_joint_names = [j.urdf for j in self.driven]
        with tempfile.TemporaryDirectory(prefix="unidextok-retarget-") as tmp:
            flat = flatten_mimic_chains(self.urdf_path, Path(tmp) / self.urdf_path.name)
            rc = RetargetingConfig(
                type="vector",
                urdf_path=str(flat),
                target_joint_names=list(self.urdf_joint_names),
                target_origin_link_names=[spec.wrist_link] * k,
                target_task_link_names=list(spec.target_links),
                target_link_human_indices=np.array([[0] * k, list(spec.target_keypoints)]),
                scaling_factor=1.0,  # set below once the reach ratio is known
                huber_delta=cfg.huber_delta,
                normal_delta=cfg.normal_delta,
                low_pass_alpha=cfg.low_pass_alpha,
            )
            quiet = logging.getLogger("dex_retargeting.yourdfpy")  # meshes are not needed for kinematics
            level, quiet.level = quiet.level, logging.ERROR
            try:
                with _temp_root(tmp):
                    self._seq = rc.build()
            finally:
                quiet.setLevel(level)
        opt = self._seq.optimizer
        self._robot = opt.robot
        self._fixed_qpos = np.clip(np.zeros(len(opt.idx_pin2fixed)), *self._robot.joint_limits[opt.idx_pin2fixed].T)
        dof_names = self._robot.dof_joint_names
        self._idx_spec_in_qpos = np.array([dof_names.index(n) for n in self.urdf_joint_names])
        self._limits = np.array(
            [[self._urdf_joints[n].lower, self._urdf_joints[n].upper] for n in self.urdf_joint_names]
        )
        self._wrist_id = self._robot.get_link_index(spec.wrist_link)
        self._target_ids = [self._robot.get_link_index(n) for n in spec.target_links]
        # robot palm frame and reach at the zero pose (clipped into the limits)
        q0 = np.clip(np.zeros(self._robot.dof), *self._robot.joint_limits.T)
        if opt.adaptor is not None:
            q0 = opt.adaptor.forward_qpos(q0)
        pos = self._link_positions(q0, [spec.wrist_link, *(spec.palm_links[key] for key in PALM_KEYS)])
        self.robot_palm = palm_frame(*pos)  # (3, 3)
        middle = spec.target_keypoints.index(self._middle_target())
        robot_reach = float(np.linalg.norm(self._link_positions(q0, [spec.target_links[middle]])[0] - pos[0]))
        self.scaling = cfg.scaling if cfg.scaling is not None else robot_reach / self._human_reach(middle)
        opt.scaling = self.scaling

    def _middle_target(self) -> int:
        """MANO-21 index of the target on the middle finger (the reach used for the scale)."""
        middle = [kp for kp in self.spec.target_keypoints if KEYPOINT_NAMES[kp].startswith("middle")]
        if not middle:
            raise URDFError(f"retarget spec {self.hand}/{self.side} has no middle-finger target; add one")
        return middle[0]

    def _human_reach(self, middle: int) -> float:
        """|wrist -> that keypoint| of the default UDHM human skeleton, flat hand (zero pose)."""
        from lerobot_unidextok.udhm.fk import forward_kinematics
        from lerobot_unidextok.udhm.skeleton import Skeleton

        kp = forward_kinematics(np.zeros((1, UDHM_DIM)), Skeleton.default(), side=self.side)[0]  # (21, 3) m
        return float(np.linalg.norm(kp[self.spec.target_keypoints[middle]] - kp[0]))

    def _link_positions(self, qpos: np.ndarray, names: list[str]) -> list[np.ndarray]:
        self._robot.compute_forward_kinematics(qpos)
        return [self._robot.get_link_pose(self._robot.get_link_index(n))[:3, 3].copy() for n in names]

    # -----------------------------------------------------------------------------------------
    def human_vectors(self, keypoints_m: np.ndarray) -> np.ndarray:
        """(T, 21, 3) keypoints (any frame) -> (T, K, 3) wrist -> target vectors in the robot's base frame (unscaled)."""
        kp = np.asarray(keypoints_m, dtype=np.float64)
        frames = palm_frame(*(kp[:, _PALM_KEYPOINTS[key]] for key in ("wrist", *PALM_KEYS)))  # (T, 3, 3)
        rel = kp[:, list(self.spec.target_keypoints)] - kp[:, :1]  # (T, K, 3)
        in_palm = np.einsum("tkc,tcd->tkd", rel, frames)  # (T, K, 3) palm coordinates
        return in_palm @ self.robot_palm.T  # (T, K, 3) robot base frame

    def qpos_to_native(self, qpos_rad: np.ndarray) -> np.ndarray:
        """(T, J) URDF angles of the spec's joints -> (T, num_native) native values of the hand spec."""
        side = self.side
        out = np.tile(np.array([j.sides[side].default_raw for j in self.hand_spec.joints], dtype=np.float64),
                      (len(qpos_rad), 1))  # fmt: skip
        names = list(self.hand_spec.joint_names)
        for c, j in enumerate(self.driven):
            q = np.clip(qpos_rad[:, c], *self._limits[c])
            out[:, names.index(j.native)] = j.to_native(q, tuple(self._limits[c]))
        return out

    def retarget(self, keypoints_m: np.ndarray) -> RetargetResult:
        """(T, 21, 3) MANO-21 keypoints in metres of one `side` hand -> robot trajectory, native and UDHM."""
        kp = np.asarray(keypoints_m, dtype=np.float64)
        if kp.ndim != 3 or kp.shape[1:] != (NUM_KEYPOINTS, 3):
            raise ValueError(f"keypoints_m must be (T, {NUM_KEYPOINTS}, 3) MANO-21 keypoints in metres; got {kp.shape}")
        if not np.isfinite(kp).all():
            raise ValueError("keypoints_m contains NaN or inf; drop or interpolate untracked frames before retargeting")
        vectors = self.human_vectors(kp)  # (T, K, 3)
        self._seq.reset()
        if self._seq.filter is not None:
            self._seq.filter.reset()
        qpos = np.zeros((len(kp), len(self.urdf_joint_names)))
        err = np.zeros((len(kp), len(self.spec.target_links)))
        for t in progress_bar(
            range(len(kp)), desc=f"retarget {self.hand}/{self.side}", disable=not self.config.progress
        ):
            q_all = self._seq.retarget(vectors[t], fixed_qpos=self._fixed_qpos)  # (dof,) incl. mimic joints
            qpos[t] = q_all[self._idx_spec_in_qpos]
            self._robot.compute_forward_kinematics(q_all)
            wrist = self._robot.get_link_pose(self._wrist_id)[:3, 3]
            robot_vec = np.stack([self._robot.get_link_pose(i)[:3, 3] - wrist for i in self._target_ids])
            err[t] = np.linalg.norm(robot_vec - self.scaling * vectors[t], axis=-1) * 1000.0
        native = self.qpos_to_native(qpos)
        udhm = np.asarray(self.hand_spec.to_udhm(native, self.side, on_out_of_range="clip"), dtype=np.float64)
        return RetargetResult(self.hand, self.side, list(self.urdf_joint_names), qpos, native, udhm, err, self.scaling)


def retarget_keypoints(
    keypoints_m: np.ndarray, hand: str, urdf: str | Path, side: str = "right", config: RetargetConfig | None = None
) -> RetargetResult:
    """One-call form of `HandRetargeter(hand, urdf, side, config).retarget(keypoints_m)`."""
    return HandRetargeter(hand, urdf, side, config).retarget(keypoints_m)
