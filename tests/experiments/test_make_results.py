"""The results page's reduced-size line: a section whose UniDexTok trained fewer steps than the shipped
schedule says so first, with where the shipped figures are."""

from experiments.config import ExperimentConfig
from experiments.make_results import reduced_size_note
from lerobot_unidextok.training import TrainConfig


def _result(train_steps: int) -> dict:
    return {"provenance": {"config": {"train": {"steps": train_steps}}}}


def test_reduced_size_note_names_the_steps_and_where_the_shipped_figures_are():
    default = ExperimentConfig().train.steps
    assert default < TrainConfig().steps  # the experiments' default size is a reduced one
    note = reduced_size_note(_result(default))
    assert note.startswith(f"**Reduced-size run: UniDexTok trained {default} steps here**")
    assert f"`configs/train/small.yaml`, {TrainConfig().steps} steps" in note
    assert '`docs/tokenizer.md`, "Measured on data the model never trained on"' in note
    assert '"The shipped universal tokenizer"' in note
    assert "trained 12 steps" in reduced_size_note(_result(12))


def test_no_reduced_size_note_at_the_shipped_schedule_or_without_tokenizer_training():
    assert reduced_size_note(_result(TrainConfig().steps)) is None
    # policy_tokens' and rate_distortion's provenance have no `train` block: their steps are not UniDexTok's
    assert reduced_size_note({"provenance": {"config": {"steps": 800}}}) is None
