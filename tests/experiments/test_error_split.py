"""The error split: through the codes it is the tokenizer's own reconstruction error; with codes placed exactly
on the group vectors, snapping costs nothing; the CLI writes its table on in-range states alone."""

import numpy as np
import pytest
import torch

from experiments import error_split
from lerobot_unidextok.evaluation import mpjae_deg, reconstruct
from lerobot_unidextok.tokenizer import EncodingConfig, UniDexTok, UniDexTokConfig
from lerobot_unidextok.training.coverage import range_states


@pytest.fixture()
def model() -> UniDexTok:
    torch.manual_seed(0)
    return UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["linkerhand_l6"])).eval()


def test_through_codes_is_the_tokenizers_reconstruction_error(model):
    data = range_states("linkerhand_l6", 50, seed=3)
    split = error_split.split_errors(model, data, EncodingConfig(rounds=2))  # the fresh model's own: nearest
    rec = reconstruct(model, data.states_rad, data.hands, allow_unknown=True).states_rad
    assert split["coded_deg"] == pytest.approx(mpjae_deg(rec, data.states_rad, data.masks), rel=1e-5)
    assert split["unsnapped_deg"] != pytest.approx(split["coded_deg"])  # random codes: snapping moves the output
    assert -1.0 <= split["cosine"] < 0.999
    assert split["searched_deg"] < split["coded_deg"]  # codes chosen through the decoder fit closer
    assert 0.0 <= split["changed_nearest"] <= 1.0 and 0.0 <= split["changed_searched"] <= 1.0


def test_codes_on_the_group_vectors_cost_nothing(model):
    """Codebooks set to one state's own group vectors (token n, group k -> code n of group k): that state's
    codes are exact, so both paths agree and the cosine is 1 (catches the unsnapped path decoding codes, or the
    cosine taken against another code)."""
    data = range_states("linkerhand_l6", 1, seed=4)
    x = torch.as_tensor(data.states_rad, dtype=torch.float32)
    with torch.no_grad():
        c = model.hand_embed(model.hand_ids("linkerhand_l6", 1))
        u = model.quantizer.unit_groups(model._encode_latent(x, c))[0]  # (N, K, d)
        n_tokens = u.shape[0]
        model.quantizer.codebooks[:, :n_tokens] = u.transpose(0, 1)  # (K, N, d)
    split = error_split.split_errors(model, data)
    assert split["cosine"] == pytest.approx(1.0, abs=1e-6)
    assert split["coded_deg"] == pytest.approx(split["unsnapped_deg"], abs=1e-4)


def test_cli_on_in_range_states_only(tmp_path):
    torch.manual_seed(0)
    folder = tmp_path / "tok"
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["human", "linkerhand_l6"])).save_pretrained(folder)
    result = error_split.run(error_split.parse([f"--checkpoint={folder}", f"--datasets=[{tmp_path / 'absent'}]",
                                                "--range_rows=20", f"--output_root={tmp_path}"]))  # fmt: skip
    assert result["skipped_datasets"] == [str(tmp_path / "absent")]
    assert all(name.startswith("in-range states: ") for name in result["sets"])
    assert np.isfinite([s["unsnapped_deg"] for s in result["sets"].values()]).all()
    md = (tmp_path / "error_split" / "error_split.md").read_text()
    assert "Skipped (absent)" in md and "in-range states: linkerhand_l6 | 20 |" in md
    with pytest.raises(FileNotFoundError, match="nothing to score"):
        error_split.run(error_split.parse([f"--checkpoint={folder}", f"--datasets=[{tmp_path / 'absent'}]",
                                           "--range_rows=0", f"--output_root={tmp_path}"]))  # fmt: skip
