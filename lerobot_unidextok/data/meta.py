"""A converted dataset's metadata, read once: `meta/info.json`, the conversion record, hand types, layouts, splits.

    meta = UdhmDatasetMeta("data/g1_udhm")          # or UdhmDatasetMeta.from_lerobot(lerobot_meta)
    meta.hand_layout()                              # HandLayout of observation.state
    meta.native_layout("action")                    # NativeLayout back to the robot's action, or None
    meta.split("auto").episodes("test")             # test episode indices

LeRobot's `LeRobotDatasetMetadata` owns `meta/info.json` for LeRobot; this class owns what a UDHM conversion adds
to it (`data.record.ConversionRecord`), so the training reader, the validator, the processor steps, the
policies and the experiments read a dataset's hands, layouts and test episodes in one way.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import json
import logging
from functools import cached_property
from pathlib import Path
from typing import Any

from lerobot_unidextok.blocks import feature_names, find_udhm_blocks, passthrough_indices
from lerobot_unidextok.constants import ACTION, CONVERSION_PATH, EPISODES_META_GLOB, HAND_TYPE_KEY, INFO_PATH, OBS_STATE
from lerobot_unidextok.data.record import ConversionRecord, load_record
from lerobot_unidextok.data.splits import EpisodeSplit, choose_split
from lerobot_unidextok.errors import InvalidInputError, MissingInputError
from lerobot_unidextok.layout import HandLayout, NativeLayout

logger = logging.getLogger(__name__)


class UdhmDatasetMeta:
    """The metadata of the converted dataset at `root` (LeRobotDataset v3.0 plus the conversion record)."""

    def __init__(self, root: str | Path, features: dict[str, dict] | None = None):
        self.root = Path(root)
        info_path = self.root / INFO_PATH
        if not info_path.is_file():
            raise MissingInputError(
                f"{self.root} is not a LeRobotDataset: {INFO_PATH} missing. Pass the root folder of a dataset "
                "converted with `unidextok-convert --source=... --input=... --root=...`"
            )
        self.info: dict[str, Any] = json.loads(info_path.read_text())
        # LeRobot's in-memory features when it hands them over (its metadata owns info.json), else the file's
        self.features: dict[str, dict] = dict(features) if features is not None else self.info.get("features", {})
        self.record: ConversionRecord | None = load_record(self.root, self.features)

    @classmethod
    def from_lerobot(cls, meta: Any) -> UdhmDatasetMeta:
        """From LeRobot's `LeRobotDatasetMetadata` (what `lerobot-train` hands a policy config): its root and
        its features."""
        return cls(meta.root, features=meta.features)

    # ----------------------------------------------------------------------------------------- basics
    @property
    def total_episodes(self) -> int:
        return int(self.info.get("total_episodes", 0))

    @property
    def fps(self) -> float:
        return float(self.info.get("fps", 0))

    @property
    def robot_type(self) -> str | None:
        return self.info.get("robot_type")

    def names(self, key: str) -> list[str]:
        """The flat column names of feature `key` ([] when the dataset has no such feature)."""
        return feature_names(self.features[key]) if key in self.features else []

    # ----------------------------------------------------------------------------------------- the record
    @cached_property
    def episode_lengths(self) -> dict[int, int] | None:
        """{episode index: length} from `meta/episodes/*.parquet` (None when absent)."""
        import pyarrow.parquet as pq  # ~0.2 s: only the split check needs it

        files = sorted(self.root.glob(EPISODES_META_GLOB))
        if not files:
            return None
        table = pq.read_table(files, columns=["episode_index", "length"])
        return dict(zip(table["episode_index"].to_pylist(), table["length"].to_pylist(), strict=True))

    @cached_property
    def record_problem(self) -> str:
        """Why the conversion record does not describe this dataset's episodes ("" when it does)."""
        record, total = self.record, self.total_episodes
        if record is None:
            return f"no {CONVERSION_PATH}"
        recorded_lengths = {e.episode_index: e.length for e in record.episodes if e.length}
        lengths = self.episode_lengths
        if record.num_episodes != total or (lengths is not None and recorded_lengths and recorded_lengths != lengths):
            return (
                f"{CONVERSION_PATH} describes {record.num_episodes} episodes but the dataset has {total} (or "
                "other episode lengths): it was edited after conversion (e.g. lerobot-edit-dataset)"
            )
        if any(not 0 <= i < total for i in record.test_episodes):
            return f"{CONVERSION_PATH} test_episodes {record.test_episodes} reach beyond the {total} episodes"
        return ""

    def recorded_split(self) -> tuple[EpisodeSplit | None, str]:
        """The dataset's own record of its test episodes: the conversion record's when it describes the dataset,
        else a `"test"` range in `meta/info.json` `splits`; (None, why there is none usable) otherwise."""
        why = self.record_problem
        if not why:
            return EpisodeSplit(self.total_episodes, tuple(self.record.test_episodes), "conversion record"), ""
        splits = self.info.get("splits") or {}
        if "test" not in splits:
            return None, f"{why}, and meta/info.json splits {sorted(splits)} have no 'test'"
        try:
            a, b = (int(x) for x in str(splits["test"]).split(":"))
        except ValueError:
            return None, f"{why}; meta/info.json splits['test'] = {splits['test']!r} is not 'a:b'"
        if not 0 <= a <= b <= self.total_episodes:
            return None, f"{why}; meta/info.json splits['test'] = {splits['test']!r} is outside 0:{self.total_episodes}"
        return EpisodeSplit(self.total_episodes, tuple(range(a, b)), "meta/info.json splits"), ""

    def split(self, holdout: str = "auto") -> EpisodeSplit:
        """The test episodes under the `holdout` policy (`data.splits`): the recorded ones, else by episode hash
        (with a warning), or an error (`holdout="recorded"`)."""
        recorded, why = self.recorded_split()
        return choose_split(self.root, self.total_episodes, recorded, why, holdout)

    # ----------------------------------------------------------------------------------------- hands
    @cached_property
    def hand_types(self) -> list[str]:
        """The distinct `hand_type` values (hand spec per block, comma-separated), sorted: from the record when
        it describes the dataset, else from the `hand_type` column of the data files."""
        if HAND_TYPE_KEY not in self.features:
            raise InvalidInputError(
                f"{self.root} has no '{HAND_TYPE_KEY}' column: it is not a converted UDHM dataset. Convert it first, "
                f"e.g. unidextok-convert --source=lerobot --input={self.root} --root=<new folder> "
                "--source_options='{\"hands\": \"<its hands>\"}' (docs/conversion.md), and use that folder"
            )
        record = self.record
        if not self.record_problem and record.episodes and all(e.hand_type for e in record.episodes):
            return sorted({e.hand_type for e in record.episodes})
        return self._hand_types_from_data()

    def _hand_types_from_data(self) -> list[str]:
        import pyarrow as pa  # only without a record: one column of every data file
        import pyarrow.compute as pc
        import pyarrow.parquet as pq

        files = sorted((self.root / "data").rglob("*.parquet"))
        if not files:
            raise MissingInputError(f"no data parquet under {self.root / 'data'}")
        column = pa.concat_arrays([pq.read_table(f, columns=[HAND_TYPE_KEY]).column(0).combine_chunks() for f in files])
        if pa.types.is_list(column.type) or pa.types.is_fixed_size_list(column.type):
            column = pc.list_flatten(column)
        return sorted(str(v) for v in pc.unique(column).to_pylist())

    def block_hands(self) -> list[str]:
        """The hand spec of each UDHM block, when every frame has the same hands; a ValueError otherwise."""
        types = self.hand_types
        if len(types) != 1:
            raise InvalidInputError(
                f"{self.root} mixes hand layouts across frames ({types}), but a processor step tokenises every "
                "frame with one fixed layout. Convert each hand into its own dataset (e.g. --max_episodes or "
                "separate inputs), mix them with unidextok-mix (a mix tokenises each row with its own hands), or "
                "pass the layout explicitly (--policy.udt_hand_layout, or hand_layout= for the step) if one layout "
                "is really meant for all frames"
            )
        return types[0].split(",")

    def hand_layout(self) -> HandLayout:
        """Blocks and sides of `observation.state` from its names, hands from `hand_type`."""
        if OBS_STATE not in self.features:
            raise InvalidInputError(f"{self.root} lacks '{OBS_STATE}'; convert it to UDHM with unidextok-convert")
        return HandLayout.from_state_names(self.names(OBS_STATE), self.block_hands())

    # ----------------------------------------------------------------------------------------- back to the robot
    def native_layout(self, key: str = ACTION) -> NativeLayout | None:
        """The layout of `key` back to the robot's own vector, or None when it has none.

        The conversion record's when there is one. Without a record (LeRobot's `lerobot-edit-dataset` drops it)
        a hands-only vector is rebuilt from the hand specs (each block's native joints, block order); a
        whole-robot vector is not (where the hands sat among the arms is unknown): None, with a warning. None
        too when `key` has no UDHM block or a hand has no native joints (a human hand's native form is
        keypoints).
        """
        names = self.names(key)
        if not names or not find_udhm_blocks(names):
            return None
        if self.record is not None:
            layout = self.record.native_layouts.get(key)
            if layout is not None and layout.names != names:
                raise InvalidInputError(
                    f"{self.root / CONVERSION_PATH} native_layout[{key!r}] names other columns than meta/info.json "
                    f"({layout.describe_converted()} vs {len(names)} columns): the dataset was changed after "
                    "conversion; convert it again"
                )
            if layout is not None:
                return layout
        hands = self.block_hands()
        from lerobot_unidextok import hands as hand_specs  # imports torch: here, not with the CLIs' configs

        if any(hand_specs.get(h).kind != "joints" for h in hands):
            return None
        if self.record is None and len(passthrough_indices(names)):
            logger.warning(
                "%s has no %s (lerobot-edit-dataset does not carry it over), so where the robot's hand columns sit "
                "among its other %s columns is unknown: %s stays in the converted layout (no native decoding). "
                "Copy %s from the dataset it was made from to decode to the robot's own vector",
                self.root, CONVERSION_PATH, key, key, CONVERSION_PATH,
            )  # fmt: skip
            return None
        sides = [b.side for b in find_udhm_blocks(names)]
        logger.info("%s records no %s native layout: each block's hand joints, block order", self.root, key)
        return NativeLayout.from_hands(hands, sides, names, mapping=self.record.mapping if self.record else "semantic")


__all__ = ["UdhmDatasetMeta"]
