"""experiments/universal_card.py on a tiny residual checkpoint: it writes the package folder of the shipped id it is
given and no other, with the residual model's encoding (the nearest codes of both stages) and its first stage alone
as the reference table; a search asked of a residual run is refused before anything is written."""

import json

import pytest
import torch

from experiments import universal_card
from experiments.universal import in_range_figures
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL, UNIVERSAL_SMALL_RESIDUAL
from lerobot_unidextok.tokenizer import NEAREST_CODES, UniDexTok, UniDexTokConfig


@pytest.fixture
def residual_run(tmp_path):
    torch.manual_seed(0)
    cfg = UniDexTokConfig.from_preset("tiny", hand_names=["human", "inspire_rh56"], residual_stages=1,
                                      trained_hands=["human", "inspire_rh56"])  # fmt: skip
    best = tmp_path / "run" / "best"
    UniDexTok(cfg).save_pretrained(best)
    (best / "training_state.json").write_text(json.dumps({"step": 10, "steps": 20, "preset": "tiny"}))
    return tmp_path / "run"


@pytest.fixture
def shipped(tmp_path, monkeypatch):
    """Both shipped ids pointed at folders under tmp_path, the old one holding a file that must survive; the
    figures on 50 in-range rows of the trained hands (the same functions, fewer rows; no converted data)."""
    folders = {UNIVERSAL_SMALL: tmp_path / "pkg" / "old", UNIVERSAL_SMALL_RESIDUAL: tmp_path / "pkg" / "new"}
    folders[UNIVERSAL_SMALL].mkdir(parents=True)
    (folders[UNIVERSAL_SMALL] / "config.json").write_text("{}")
    monkeypatch.setattr(universal_card, "SHIPPED", folders)
    monkeypatch.setattr(universal_card, "figures",
                        lambda model, datasets, hands, stages=None: in_range_figures(model, hands, rows=50,
                                                                                     stages=stages))  # fmt: skip
    return folders


def test_writes_the_residual_id_only_with_its_first_stage_as_the_reference(residual_run, shipped):
    universal_card.main([f"--repo_id={UNIVERSAL_SMALL_RESIDUAL}", f"--run={residual_run}", "--cpu_s=120",
                         "--commit=HEAD", "--encoding.rounds=0", "--nice=5",
                         "--train_flags=--preset=small_residual --encoding.rounds=0"])  # fmt: skip
    new = shipped[UNIVERSAL_SMALL_RESIDUAL]
    assert (shipped[UNIVERSAL_SMALL] / "config.json").read_text() == "{}"  # the other shipped folder untouched
    assert {p.name for p in new.iterdir()} >= {"config.json", "model.safetensors", "README.md", "eval.json"}
    model = UniDexTok.from_pretrained(new)
    assert model.config.encoding == NEAREST_CODES and model.config.residual_stages == 1
    recorded = json.loads((new / "eval.json").read_text())
    assert set(recorded["results"]) == set(recorded["first_stage"]) == {
        "in-range states: human", "in-range states: inspire_rh56"}
    assert "nearest_codes" not in recorded and recorded["symbols_per_hand"] == {"all stages": 64, "first stage": 32}
    for name, entry in recorded["results"].items():  # untrained: two measurements of the same rows, not a ranking
        assert entry["rows"] == recorded["first_stage"][name]["rows"] == 50
        assert entry["mpjae_deg"] != recorded["first_stage"][name]["mpjae_deg"], name
    assert recorded["commands"]["train"] == ("nice -n 5 unidextok-train --config_path=train/universal "
                                             "--preset=small_residual --encoding.rounds=0")  # fmt: skip
    figures_cmd = recorded["commands"]["figures"]
    assert f"--repo_id={UNIVERSAL_SMALL_RESIDUAL}" in figures_cmd and "--encoding.rounds=0" in figures_cmd
    card = (new / "README.md").read_text()
    assert f"# {UNIVERSAL_SMALL_RESIDUAL}" in card and "64 codes per hand" in card
    assert "`eval.json` `first_stage`" in card and recorded["commands"]["train"] in card and "2.0 CPU-minutes" in card


def test_a_search_asked_of_a_residual_run_is_refused_before_writing(residual_run, shipped, capsys):
    with pytest.raises(SystemExit) as err:
        universal_card.main([f"--repo_id={UNIVERSAL_SMALL_RESIDUAL}", f"--run={residual_run}", "--cpu_s=1",
                             "--encoding.rounds=2"])  # fmt: skip
    assert err.value.code == 2
    assert "--encoding.rounds=0" in capsys.readouterr().err
    assert not shipped[UNIVERSAL_SMALL_RESIDUAL].exists()
