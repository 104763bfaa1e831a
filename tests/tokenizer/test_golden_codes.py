"""Old checkpoints encode exactly as before `EncodingConfig` and the residual stage existed.

`golden_codes.json` holds fixed in-range rows of every hand the shipped `unidextok/universal-small` knows (and one
it does not, zero-shot) with the codes the shipped model gave them at commit a33cb3b, before the encoding became
one `EncodingConfig`: its own encoding (2 rounds of the greedy search, up to 16 changes, rows within 0.1 deg stop)
and the nearest codes. Regenerate (only on purpose, e.g. for a new shipped model) with

    .venv/bin/python tests/tokenizer/test_golden_codes.py --write

which uses only calls that existed at a33cb3b (`from_pretrained`, `encode` with the model's own encoding,
`quantizer.nearest_indices(embed(...))`), so the same command recorded the fixture from that commit.
"""

import json
import shutil
import sys
from pathlib import Path

import torch

from lerobot_unidextok.pretrained import SHIPPED, UNIVERSAL_SMALL
from lerobot_unidextok.tokenizer import UniDexTok
from lerobot_unidextok.training.coverage import range_states

GOLDEN = Path(__file__).parent / "golden_codes.json"
ZERO_SHOT = "unitree_dex3_1"  # registered, never trained: the unknown-hand embedding, no search (no spec mask)
ROWS_PER_HAND = 3


def record(model: UniDexTok) -> dict:
    """{hand: {states_rad, codes (the model's own encoding), nearest (nearest codes)}} on fixed rows."""
    out = {}
    for hand in [*model.config.trained_hands, ZERO_SHOT]:
        x = torch.tensor(range_states(hand, ROWS_PER_HAND, 11).states_rad)
        x = torch.tensor([[round(v, 6) for v in row] for row in x.tolist()])  # what the JSON holds
        nearest = model.quantizer.nearest_indices(model.embed(x, hand, allow_unknown=True))
        codes = model.encode(x, hand, allow_unknown=True)
        out[hand] = {"states_rad": x.tolist(), "codes": codes.tolist(), "nearest": nearest.tolist()}
    return out


if __name__ == "__main__" and "--write" in sys.argv:
    torch.set_num_threads(1)
    hands = record(UniDexTok.from_pretrained(UNIVERSAL_SMALL))
    about = ("codes of lerobot_unidextok/pretrained/universal-small (its own encoding, and the nearest codes) on "
             "fixed in-range rows; regenerate: .venv/bin/python tests/tokenizer/test_golden_codes.py --write")
    GOLDEN.write_text(json.dumps({"about": about, "commit": "a33cb3b", "hands": hands}, separators=(",", ":")) + "\n")
    print(f"wrote {GOLDEN}: {len(hands)} hands x {ROWS_PER_HAND} rows")


def _golden() -> dict:
    return json.loads(GOLDEN.read_text())["hands"]


def _assert_encodes_as_recorded(model: UniDexTok) -> None:
    """Identical codes on every recorded row, the model's own encoding and the nearest codes. (The search's
    discrete choices are sums whose rounding could differ on another CPU or BLAS build, tests/pretrained/
    test_shipped.py; on the machine that recorded the fixture they are bit-identical, and a tolerance would hide
    a lost setting: 2 rounds without the 0.1 deg stop change only 0.4 % of these codes.)"""
    from lerobot_unidextok.tokenizer import NEAREST_CODES

    for hand, entry in _golden().items():
        x = torch.tensor(entry["states_rad"])
        nearest = model.encode(x, hand, allow_unknown=True, encoding=NEAREST_CODES)
        assert torch.equal(nearest, torch.tensor(entry["nearest"])), hand
        assert torch.equal(model.encode(x, hand, allow_unknown=True), torch.tensor(entry["codes"])), hand


def test_the_shipped_model_encodes_as_before():
    from lerobot_unidextok.tokenizer import EncodingConfig

    model = UniDexTok.from_pretrained(UNIVERSAL_SMALL)
    assert model.config.encoding == EncodingConfig(rounds=2, method="greedy", changes=16, tolerance_deg=0.1)
    _assert_encodes_as_recorded(model)


def test_a_checkpoint_with_the_flat_legacy_config_encodes_as_before(tmp_path):
    """The shipped weights with the config.json the package shipped at a33cb3b (the flat `search_*` keys,
    `legacy_config_universal_small.json`, verbatim): upgraded on load into the same encoding, the same codes;
    saved again, it is written in the new form and still encodes so."""
    from lerobot_unidextok.tokenizer import EncodingConfig

    folder = tmp_path / "old"
    shutil.copytree(SHIPPED[UNIVERSAL_SMALL], folder)
    legacy = (Path(__file__).parent / "legacy_config_universal_small.json").read_text()
    assert '"search_rounds": 2' in legacy and '"encoding"' not in legacy
    (folder / "config.json").write_text(legacy)
    old = UniDexTok.from_pretrained(folder)
    assert old.config.encoding == EncodingConfig(rounds=2, method="greedy", changes=16, tolerance_deg=0.1)
    _assert_encodes_as_recorded(old)
    old.save_pretrained(tmp_path / "resaved")
    written = json.loads((tmp_path / "resaved" / "config.json").read_text())
    assert written["encoding"]["rounds"] == 2 and not any(k.startswith("search_") for k in written)
    assert UniDexTok.from_pretrained(tmp_path / "resaved").config == old.config
