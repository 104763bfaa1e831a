"""Where a tokenizer's error comes from: the code snapping, or the encoder and decoder themselves.

Each state goes through the tokenizer twice: through its codes (`encode` then `decode`, what the tokenizer
gives), and with the quantiser's snapping left out (the decoder fed the unit-norm group vectors the codes are
searched for, `quantizer.unit_groups`). The second error is what the same networks would reach with infinitely
fine codes; the difference is the cost of snapping to 32 codes per group. The mean cosine between each group
vector and its code says how close the encoder already puts its vectors to the codes. A third path keeps the
codes but picks them with the decoder-aware code search (`tokenizer/search.py`; the checkpoint's own encoding,
or `--encoding.*`): how much of the snapping cost better-chosen codes win back. Last, how
stable each encoding is: the share of code positions that change when every active joint moves by NUDGE_DEG.

    python experiments/error_split.py                         # the shipped unidextok/universal-small
    python experiments/error_split.py --checkpoint=outputs/unidextok_universal/best
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import git_commit, md_table
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL
from lerobot_unidextok.tokenizer import NEAREST_CODES, EncodingConfig

NAME = "error_split"
NUDGE_DEG = 0.5  # joint motion for the codes' sensitivity: about the tokenizer's own error


@dataclass
class ErrorSplitConfig:
    checkpoint: str = UNIVERSAL_SMALL  # a local folder, a shipped id or a Hub repo id
    # Converted UDHM datasets scored on their test split (absent ones are skipped with a note).
    datasets: list[str] = field(
        default_factory=lambda: ["outputs/universal_data/g1_inspire", "outputs/universal_data/human_clip"]
    )
    range_rows: int = 2000  # states per registered hand uniform inside its registered ranges (0 = none)
    range_seed: int = 1  # not 0: the card's in-range figures use seed 0
    # the encoding of the third path: None = the checkpoint's own (the shipped one's: 2 rounds of the greedy search)
    encoding: EncodingConfig | None = None
    output_root: str = "outputs/experiments"


def split_errors(model, data, encoding: EncodingConfig | None = None) -> dict:
    """{rows, coded_deg, unsnapped_deg, searched_deg, cosine, changed_nearest, changed_searched} of one set of
    hand states (`HandStates`)."""
    import torch

    from lerobot_unidextok.evaluation import mpjae_deg

    x = torch.as_tensor(data.states_rad, dtype=torch.float32)  # (B, 22)
    with torch.no_grad():
        c = model.hand_embed(model.hand_ids(list(data.hands), len(x), allow_unknown=True))  # (B, C)
        z = model._encode_latent(x, c)  # (B, N, C)
        vq = model.quantizer
        u = vq.unit_groups(z)  # (B, N, K, d)
        codes = vq.nearest_indices(z)  # (B, N, K)
        coded = model._decode_latent(vq.get_output_from_indices(codes), c)  # (B, 22)
        unsnapped = model._decode_latent(vq.project_out(u.flatten(-2)), c)  # (B, 22)
        cosine = (u * vq.indices_to_codes(codes)).sum(-1).mean()
        found = model.encode(x, list(data.hands), allow_unknown=True, mask=torch.tensor(data.masks),
                             encoding=encoding)  # (B, N, K)
        searched = model._decode_latent(vq.get_output_from_indices(found), c)  # (B, 22)
    return {"rows": len(x), "coded_deg": mpjae_deg(coded.numpy(), data.states_rad, data.masks),
            "unsnapped_deg": mpjae_deg(unsnapped.numpy(), data.states_rad, data.masks),
            "searched_deg": mpjae_deg(searched.numpy(), data.states_rad, data.masks), "cosine": float(cosine),
            "changed_nearest": changed_share(model, x, data, codes, NEAREST_CODES),
            "changed_searched": changed_share(model, x, data, found, encoding)}  # fmt: skip


def changed_share(model, x, data, codes, encoding: EncodingConfig | None) -> float:
    """Mean share of the N x K code positions that change when every active joint of every row moves by
    NUDGE_DEG (random sign, seed 0), the codes picked as `codes` were (`encoding`, None = the model's own)."""
    import numpy as np
    import torch

    signs = np.random.default_rng(0).choice([-1.0, 1.0], size=data.states_rad.shape)  # (B, 22)
    moved = x + torch.as_tensor(np.radians(NUDGE_DEG) * signs * data.masks, dtype=torch.float32)  # (B, 22)
    again = model.encode(moved, list(data.hands), allow_unknown=True, mask=torch.tensor(data.masks),
                         encoding=encoding)  # (B, N, K)
    return float((again != codes).float().mean())


def run(cfg: ErrorSplitConfig) -> dict:
    from experiments.rate_distortion import test_and_range_sets
    from lerobot_unidextok.tokenizer import UniDexTok

    model = UniDexTok.from_pretrained(cfg.checkpoint)
    present = [root for root in cfg.datasets if Path(root).is_dir()]
    skipped = [root for root in cfg.datasets if root not in present]
    sets = test_and_range_sets(present, [], cfg.range_rows, cfg.range_seed)
    if not sets:
        raise FileNotFoundError(f"none of {cfg.datasets} exists and range_rows=0: nothing to score")
    result = {"experiment": NAME, "checkpoint": cfg.checkpoint, "config": dataclasses.asdict(cfg),
              "skipped_datasets": skipped,
              "encoding": (cfg.encoding or model.config.encoding).describe(),
              "sets": {name: split_errors(model, data, cfg.encoding) for name, data in sets.items()},
              "git_commit": git_commit(), "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    folder = Path(cfg.output_root) / NAME
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def markdown(result: dict) -> str:
    rows = [[name, s["rows"], f"{s['coded_deg']:.3f}", f"{s['unsnapped_deg']:.3f}",
             f"{s['coded_deg'] - s['unsnapped_deg']:+.3f}", f"{s['cosine']:.5f}", f"{s['searched_deg']:.3f}",
             _share(s.get("changed_nearest")), _share(s.get("changed_searched"))]
            for name, s in result["sets"].items()]  # fmt: skip
    note = f" Skipped (absent): {', '.join(result['skipped_datasets'])}." if result["skipped_datasets"] else ""
    return "\n".join([
        f"# {NAME}", "",
        f"Checkpoint `{result['checkpoint']}`. MPJAE (deg) through the codes, and with the decoder fed the "
        "unsnapped group vectors (no code snapping); cosine = mean cosine between a group vector and its code; "
        f"searched = through codes picked by the code search ({result.get('encoding', 'its own encoding')}); "
        f"codes changed = mean share of the 64 code positions that change when every active joint moves by "
        f"{NUDGE_DEG} deg, nearest / searched." + note, "",
        md_table(["set", "rows", "through codes (deg)", "unsnapped (deg)", "snapping costs (deg)", "cosine",
                  "searched (deg)", "codes changed, nearest", "codes changed, searched"], rows),
    ])  # fmt: skip


def _share(x: float | None) -> str:
    return "-" if x is None else f"{x:.2f}"


def parse(argv: list[str] | None = None) -> ErrorSplitConfig:
    return runtime.parse(ErrorSplitConfig, argv)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(ErrorSplitConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
