"""The rate-distortion experiment: entropy and bits arithmetic on worked examples, binning's error bound, and an
end-to-end run of an untrained tiny tokenizer on a converted sample dataset (no ../shared needed)."""

import json
import math

import numpy as np
import pytest

from experiments import rate_distortion as rd
from experiments.unseen_data import hand_binning
from lerobot_unidextok.training.coverage import range_states


# ---------------------------------------------------------------------------------------------
# arithmetic
# ---------------------------------------------------------------------------------------------
def test_entropy_and_rate_of_a_worked_example():
    # position 0: codes 0,1,0,1 -> p = (1/2, 1/2) -> 1 bit; position 1: always 7 -> 0 bits;
    # position 2: 0,1,2,2 -> p = (1/4, 1/4, 1/2) -> 1/4*2 + 1/4*2 + 1/2*1 = 1.5 bits
    codes = np.array([[0, 7, 0], [1, 7, 1], [0, 7, 2], [1, 7, 2]])
    np.testing.assert_allclose(rd.entropy_bits(codes), [1.0, 0.0, 1.5])
    assert rd.measured_rate_bits(codes) == pytest.approx(2.5)
    # 32 equiprobable codes at one position: log2(32) = 5 bits, the nominal bits of one UniDexTok group
    assert rd.measured_rate_bits(np.arange(32)[:, None]) == pytest.approx(5.0)
    with pytest.raises(ValueError, match="rows >= 1"):
        rd.entropy_bits(np.zeros((0, 3), int))


def test_coded_bits_of_a_worked_example():
    # fitted on 0,0,0,1 at one position over an alphabet of 2: counts + 1/2 = (3.5, 1.5) of 5; coding 0 then 1:
    # -log2(3.5/5) - log2(1.5/5) = 0.515 + 1.737 bits over 2 rows
    fit, codes = np.array([[0], [0], [0], [1]]), np.array([[0], [1]])
    assert rd.coded_bits(fit, codes, 2) == pytest.approx((-math.log2(0.7) - math.log2(0.3)) / 2)
    # a symbol never seen in fitting still has a code: 1/2 of (4 + 32/2) over an alphabet of 32
    assert rd.coded_bits(np.zeros((4, 1), int), np.array([[31]]), 32) == pytest.approx(-math.log2(0.5 / 20))
    # positions add up; fitting on many uniform rows costs about log2(alphabet) per position
    rng = np.random.default_rng(0)
    uniform = rng.integers(0, 32, (20000, 3))
    assert rd.coded_bits(uniform[:10000], uniform[10000:], 32) == pytest.approx(15.0, abs=0.05)
    with pytest.raises(ValueError, match="alphabet"):
        rd.coded_bits(fit, np.array([[2]]), 2)


def test_the_lower_bound_is_below_binning_by_log2_e_over_2_per_joint():
    """Uniform binning at b bits has MAE = bin / 4; the Shannon lower bound at that MAE is b - log2(e / 2) bits per
    joint for a hand with one side (the human hand: the UDHM limits)."""
    data = range_states("human", 200, seed=3)
    binning = hand_binning("human", 256)
    mask = binning.ranges["human"].active_mask
    mae_deg = float(np.degrees(binning.bin_width_rad("human")[mask]).mean() / 4)
    # equal bins on every joint would give exactly 8 - 0.443 per joint; widths differ, so compare per joint
    widths = binning.bin_width_rad("human")[mask]
    want = float(np.sum(np.log2(widths * 256)) - mask.sum() * math.log2(2 * math.e * math.radians(mae_deg)))
    assert rd.slb_bits(data, mae_deg) == pytest.approx(want, rel=1e-6)
    equal = float(np.sum(np.log2(widths * 256)) - np.sum(np.log2(2 * math.e * widths / 4)))
    assert equal == pytest.approx(mask.sum() * (8 - math.log2(math.e / 2)), rel=1e-6)


def test_pca_code_gets_finer_with_its_step_and_names_its_tokens():
    data, fit = range_states("inspire_rh56_unitree", 300, seed=3), range_states("inspire_rh56_unitree", 600, seed=4)
    curve = rd.pca_curve(data, fit, max_bits=6)
    assert [c["bits"] for c in curve][:5] == [1.0, 1.25, 1.5, 1.75, 2.0] and curve[-1]["bits"] == 8.0
    errs, bits = [c["mpjae_deg"] for c in curve], [c["coded_bits"] for c in curve]
    assert errs[-1] < errs[0] / 50 and bits[-1] > bits[0]
    assert all(c["tokens"] == 6 for c in curve[8:])  # six DoFs, six coefficients that vary


def test_equal_bits_picks_the_largest_b_within_the_rate_and_the_smallest_b_that_matches():
    curve = [{"bits": b, "nominal_bits": 6.0 * b, "mpjae_deg": 12.0 / 2**b} for b in range(1, 9)]
    # 6 DoFs: b = 3 is 18 bits <= 20 < 24; 12 / 2**b <= 1.0 first at b = 4 (0.75)
    eq = rd.equal_bits({"rate_bits": 20.0, "mpjae_deg": 1.0}, curve)
    assert eq["at_rate"]["bits"] == 3 and eq["to_match"]["bits"] == 4
    # an error binning never reaches within 8 bits, and a rate below its 1-bit cost: no b qualifies
    eq = rd.equal_bits({"rate_bits": 5.0, "mpjae_deg": 0.01}, curve)
    assert eq == {"at_rate": None, "to_match": None}


def test_verdict_of_a_worked_example():
    def row(rate, mpjae, match_bits, within_mpjae):
        match = {"nominal_bits": match_bits} if match_bits else None
        return {"unidextok": {"rate_bits": rate, "nominal_bits": 320.0, "mpjae_deg": mpjae},
                "equal_bits": {"to_match": match, "at_rate": {"mpjae_deg": within_mpjae}}}  # fmt: skip

    # set 1: 100 / 50 = 2x fewer bits than the measured rate, 320 / 50 = 6.4x than nominal, MPJAE 1.0 / 0.25 = 4x
    # set 2: binning never matches 0.05 deg within 8 bits; within the rate UniDexTok is 0.05 / 0.25 = 0.2 of it
    result = {"config": {"max_bits": 8}, "rows": [row(100.0, 1.0, 50.0, 0.25), row(60.0, 0.05, None, 0.25)]}
    assert rd.verdict(result) == (
        "Binning reaches UniDexTok's MPJAE on 1 of 2 sets with 2.0-2.0x fewer bits than UniDexTok's measured rate "
        "(6.4-6.4x fewer than its nominal bits). On 1 of 2 sets binning needs more than b = 8. Within UniDexTok's "
        "measured rate (b capped at 8), binning's MPJAE is lower on 1 of 2 sets (UniDexTok's MPJAE over binning's: "
        "0.20-4.00; below 1, UniDexTok is the more accurate)."
    )


@pytest.mark.parametrize("hand", ["inspire_rh56_unitree", "human"])
def test_binning_at_b_bits_is_within_half_a_bin(hand):
    data = range_states(hand, 400, seed=3)
    binning_dofs = int(data.masks.any(0).sum())
    previous = math.inf
    for b in range(1, 9):
        binning = hand_binning(hand, 2**b)
        mask = binning.ranges[hand].active_mask
        pred = binning.decode(binning.encode(data.states_rad, hand), hand).numpy()
        err = np.abs(pred - data.states_rad)[:, mask]  # (rows, active DoFs) radians
        assert (err <= binning.bin_width_rad(hand) / 2 + 1e-6).all()
        point = rd.binning_point(data, b)
        assert point["nominal_bits"] == b * binning_dofs
        # uniform states fill every bin: the measured rate is close to, and never above, the nominal bits
        assert 0.9 * point["nominal_bits"] <= point["rate_bits"] <= point["nominal_bits"] + 1e-9
        assert point["mpjae_deg"] < previous / 1.8  # one more bit halves the error (uniform states: bin / 4)
        previous = point["mpjae_deg"]


def test_config_rejects_the_cards_seed_and_an_empty_run():
    with pytest.raises(ValueError, match="range_seed 0"):
        rd.RateDistortionConfig(range_seed=0)
    with pytest.raises(ValueError, match="nothing to score"):
        rd.RateDistortionConfig(datasets=[], range_rows=0)


def test_missing_dataset_names_the_command_that_writes_it(tmp_path):
    cfg = rd.RateDistortionConfig(datasets=[str(tmp_path / "absent")], range_rows=0)
    with pytest.raises(FileNotFoundError, match="experiments/universal_data.py"):
        rd.evaluation_sets(cfg)


# ---------------------------------------------------------------------------------------------
# end to end
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def converted_linker(tmp_path_factory):
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import write_samples

    raw = write_samples(tmp_path_factory.mktemp("raw"), sources=["linkerhand"], episodes_per_source=5,
                        frames_per_episode=30)["linkerhand"]  # fmt: skip
    root = tmp_path_factory.mktemp("conv") / "linker"
    convert(ConvertOptions(source="linkerhand", input=raw, root=root, progress=False))
    return root


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory):
    from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

    path = tmp_path_factory.mktemp("tok") / "tiny"
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["linkerhand_l10"])).save_pretrained(path)
    return path


def test_runs_end_to_end_and_fills_its_results_page_section(converted_linker, tiny_checkpoint, tmp_path):
    from experiments.make_results import update_sections
    from lerobot_unidextok.tokenizer import UniDexTok

    argv = [f"--checkpoint={tiny_checkpoint}", f"--datasets=[{converted_linker}]",
            "--range_hands=[linkerhand_l10,human]", "--range_rows=60", "--fit_rows=80", "--max_bits=4",
            f"--output_root={tmp_path}"]  # fmt: skip
    result = rd.run(rd.parse(argv))
    cfg = UniDexTok.from_pretrained(str(tiny_checkpoint)).config
    nominal = cfg.num_tokens * cfg.num_groups * math.log2(cfg.codebook_size)
    sets = {r["set"]: r for r in result["rows"]}
    test_sets = [s for s in sets if s.startswith("linker test episodes: ")]
    assert test_sets and {"in-range states: linkerhand_l10", "in-range states: human"} <= set(sets)
    for r in sets.values():
        u = r["unidextok"]
        assert u["nominal_bits"] == nominal
        assert 0.0 <= u["rate_bits"] <= min(nominal, cfg.num_tokens * cfg.num_groups * math.log2(r["rows"])) + 1e-9
        assert [c["bits"] for c in r["binning"]] == [1, 2, 3, 4]
        assert [c["nominal_bits"] for c in r["binning"]] == [b * r["dofs"] for b in (1, 2, 3, 4)]
        assert r["equal_bits"] == rd.equal_bits(u, r["binning"])
    assert sets["in-range states: human"]["dofs"] == 22 and not sets["in-range states: human"]["known_hand"]
    for r in sets.values():  # entropy-coded bits beside the measured rate, priors fitted on other rows
        assert r["fit_rows"] > 0 and r["unidextok"]["coded_bits"] > 0 and r["pca"][0]["coded_bits"] > 0
        assert all(c["coded_bits"] > 0 for c in r["binning"]) and ("slb" in r) == ("in-range" in r["set"])
    assert "At 8-bit binning's error" not in rd.markdown(result)  # max_bits 4: no 8-bit reference, no table

    folder = tmp_path / "rate_distortion"
    assert json.loads((folder / "rate_distortion.json").read_text())["rows"] == result["rows"]
    md = (folder / "rate_distortion.md").read_text()
    assert md == rd.markdown(result) + "\n" and "| in-range states: human (unknown hand) | 60 | 22 | " in md
    assert (folder / "rate_distortion.png").stat().st_size > 10_000

    page = tmp_path / "RESULTS.md"
    page.write_text("# Results\n\nintro\n\n## main_table\n\nmeasured elsewhere\n")
    text = update_sections(tmp_path, page, ["rate_distortion"])
    assert "measured elsewhere" in text and "## rate_distortion\n\nCommand: `python experiments/rate_distortion.py --checkpoint=" in text
    assert f"tokenizer `{tiny_checkpoint}` (untrained)" in text and "Reduced-size run" not in text
    assert rd.summary_table(result) in text and rd.verdict(result) in text
