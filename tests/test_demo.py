"""`make demo`'s entry point: the module it runs (run end to end, tiny, by tests/test_wheel.py from the installed
wheel) and its LeRobot stage offline."""

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]


def test_make_demo_runs_the_demo_module():
    """tests/test_wheel.py runs the demo module end to end from the installed wheel (every stage, tiny sizes);
    this pins that it is what `make demo` runs."""
    makefile = (REPO_ROOT / "Makefile").read_text()
    recipe = makefile.split("\ndemo:")[1].split("\n\n")[0]
    assert "-m lerobot_unidextok.demo $(ARGS)" in recipe


def test_demo_lerobot_stage_under_hf_hub_offline(g1_like, tmp_path, capsys):
    """With HF_HUB_OFFLINE=1 (set by this test session, and by users who want no network) the demo's last
    stage crashed after the whole run ('HF_HUB_OFFLINE is set: unset it ... to push'); it now runs the
    processor step and skips only the loopback hub-cache step, saying why."""
    import torch

    from lerobot_unidextok.demo import demo_lerobot
    from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

    torch.manual_seed(0)
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["inspire_rh56_unitree"])).save_pretrained(
        tmp_path / "tokenizer"
    )
    demo_lerobot(tmp_path, {"lerobot": g1_like["root"]})
    text = capsys.readouterr().out
    assert "processor output keys" in text and "observation.hand_tokens" in text
    assert "local hub cache step skipped: HF_HUB_OFFLINE is set" in text
