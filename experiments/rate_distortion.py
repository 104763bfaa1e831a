"""Rate-distortion of a UniDexTok checkpoint against per-joint uniform binning, at equal bits per hand state.

    python experiments/rate_distortion.py                                   # the shipped unidextok/universal-small
    python experiments/rate_distortion.py --checkpoint=outputs/unidextok_universal/best --range_rows=1000

Evaluation sets, one hand each: the test split of each converted dataset (default: the real G1 Inspire
recordings and the real human clip as `experiments/universal_data.py` converts them), and every registered
hand on `range_rows` states uniform inside its registered joint ranges (`training.coverage.range_states`, seed
`range_seed`; the card's in-range figures use seed 0, so this set is a different draw). Per set:

- UniDexTok: nominal bits = N tokens x K groups x log2(codebook size); measured rate = the sum over the N x K
  code positions of the empirical (plug-in) entropy of that position's code on the set, an upper bound of
  the joint entropy of the codes (the positions are not independent), itself estimated from the set's rows
  (a plug-in estimate is biased low on small sets: at most log2(rows) bits per position); MPJAE (deg).
- Per-joint uniform binning over the hand's registered range (`unseen_data.hand_binning`) at b = 1..`max_bits`
  bits per active joint: nominal bits = b x active DoFs, the same entropy of its codes, MPJAE.
- Binning at equal bits: binning at the largest b whose nominal bits fit in UniDexTok's measured rate, and
  the smallest b whose MPJAE matches or beats UniDexTok's (the bits binning needs for UniDexTok's error).

Entropy-coded bits (`coded_bits`), the rate an arithmetic coder with a fixed model would spend: each code position
(UniDexTok's N x K positions, binning's joints, PCA's coefficients) gets a categorical prior fitted on other rows
of the same hand (add-1/2 smoothing over its alphabet, so a symbol never seen in fitting still has a code):
the dataset's training-split rows for a test-episode set, `fit_rows` in-range states of seed `range_seed + 1` for
an in-range set; the set's bits are the mean code length of its rows under those priors. Beside binning and
UniDexTok (the checkpoint's encoding and the nearest codes), a transform code: PCA of the fitting rows (active
DoFs, each scaled by its registered range), every coefficient uniformly quantised with the same step and
entropy-coded the same way (the joint synergies PCA shows, used as a code). On in-range states (independent
uniform joints) no code can beat binning by much: the Shannon lower bound for mean absolute error,
R(D) >= h(X) - n log2(2 e D) (h(X) the states' differential entropy, at least the mean over sides of the sum of
log2 of the active joints' ranges; n active DoFs), is `slb_bits`; binning at b bits has D = bin / 4 and spends b
bits per joint, log2(e / 2) = 0.44 bits per joint above the bound.

The prompt table (`prompt_table`): per set, 8-bit binning's MPJAE and entropy-coded bits, the bound at that
MPJAE, the fewest PCA and UniDexTok coded bits reaching it, and the token count a VLA prompt carries for the
state at that error: binning one 256-symbol token per active joint, UniDexTok N x K tokens of its codebook size
(when it reaches the error at all), PCA one token per coefficient that takes more than one value.

Writes `<output_root>/rate_distortion/rate_distortion.{json,md}` and `rate_distortion.png`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import git_commit, md_table
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL
from lerobot_unidextok.tokenizer import NEAREST_CODES, EncodingConfig
from lerobot_unidextok.training import HandStates

NAME = "rate_distortion"
DEFAULT_DATASETS = ("outputs/universal_data/g1_inspire", "outputs/universal_data/human_clip")
DATA_COMMAND = "python experiments/universal_data.py --out=outputs/universal_data"


@dataclass
class RateDistortionConfig:
    # Tokenizer checkpoint: a local folder, a shipped id or a Hub repo id.
    checkpoint: str = UNIVERSAL_SMALL
    # Converted UDHM datasets (local roots) scored on their test split, one set per hand in each.
    datasets: list[str] = field(default_factory=lambda: list(DEFAULT_DATASETS))
    # Registered hands scored on states uniform inside their registered ranges; empty = every registered hand.
    range_hands: list[str] = field(default_factory=list)
    range_rows: int = 5000  # in-range states per hand (0 = no in-range sets)
    range_seed: int = 1  # not 0: the card's in-range figures use seed 0
    fit_rows: int = 2000  # in-range states per hand (seed range_seed + 1) the entropy coders' priors are fitted on
    max_bits: int = 12  # binning at b = 1..max_bits bits per active joint
    # How codes are picked (docs/tokenizer.md "Code search"): None = the checkpoint's own encoding,
    # --encoding.rounds=0 = the nearest codes (the paper's encoding).
    encoding: EncodingConfig | None = None
    output_root: str = "outputs/experiments"

    def __post_init__(self) -> None:
        if not 1 <= self.max_bits <= 16:
            raise ValueError(f"max_bits must be in [1, 16], got {self.max_bits}")
        if self.range_rows < 0:
            raise ValueError(f"range_rows must be >= 0, got {self.range_rows}")
        if self.fit_rows < 1:
            raise ValueError(f"fit_rows must be >= 1 (the entropy coders' priors are fitted on them), got {self.fit_rows}")
        if self.range_seed == 0:
            raise ValueError("range_seed 0 draws the card's own in-range states; pick another seed, e.g. 1")
        if not self.datasets and self.range_rows == 0:
            raise ValueError("nothing to score: pass --datasets='[...]' or --range_rows > 0")


# ---------------------------------------------------------------------------------------------
# rate arithmetic
# ---------------------------------------------------------------------------------------------
def entropy_bits(codes: np.ndarray) -> np.ndarray:
    """(M, P) integer codes -> (P,) empirical entropy in bits of each position's code over the M rows."""
    codes = np.asarray(codes)
    if codes.ndim != 2 or codes.shape[0] == 0:
        raise ValueError(f"codes must be (rows, positions) with rows >= 1, got shape {codes.shape}")
    out = np.zeros(codes.shape[1])
    for p in range(codes.shape[1]):
        _, counts = np.unique(codes[:, p], return_counts=True)
        q = counts / codes.shape[0]
        out[p] = max(0.0, float(-(q * np.log2(q)).sum()))
    return out


def measured_rate_bits(codes: np.ndarray) -> float:
    """Sum over code positions of each position's empirical entropy (bits per state)."""
    return float(entropy_bits(codes).sum())


def coded_bits(fit_codes: np.ndarray, codes: np.ndarray, alphabet: int | np.ndarray) -> float:
    """Mean bits per row of (M, P) integer `codes` under per-position categorical priors fitted on (F, P)
    `fit_codes` with add-1/2 (Krichevsky-Trofimov) smoothing over `alphabet` symbols per position (one size, or
    (P,) sizes; symbols are 0..alphabet-1): the code length of an arithmetic coder with that fixed model."""
    fit_codes, codes = np.asarray(fit_codes), np.asarray(codes)
    if fit_codes.ndim != 2 or codes.ndim != 2 or fit_codes.shape[1] != codes.shape[1] or not len(codes):
        raise ValueError(f"codes must be (rows, positions) with the same positions, got {fit_codes.shape} and {codes.shape}")
    sizes = np.broadcast_to(np.asarray(alphabet), (codes.shape[1],))
    if (codes < 0).any() or (codes >= sizes).any() or (fit_codes < 0).any() or (fit_codes >= sizes).any():
        raise ValueError("codes must lie in [0, alphabet) at every position")
    total = 0.0
    for p in range(codes.shape[1]):
        counts = np.bincount(fit_codes[:, p], minlength=int(sizes[p])).astype(float) + 0.5
        total -= np.log2(counts[codes[:, p]] / counts.sum()).sum()
    return float(total / len(codes))


def slb_bits(data: HandStates, mpjae_deg: float) -> float:
    """Shannon lower bound (bits per state) of any code of `data`'s hand's in-range states at mean absolute error
    `mpjae_deg` over its active DoFs: h(X) - n log2(2 e D), with h(X) >= the mean over the hand's sides of the sum
    of log2(range) of its active joints (radians; the states are uniform inside one side's ranges each)."""
    from lerobot_unidextok.training.coverage import range_only_table

    mask, lo, hi = range_only_table(_one_hand(data))
    entropy = float(np.mean([np.log2(h[mask] - l[mask]).sum() for l, h in zip(lo, hi, strict=True)]))  # noqa: E741
    return entropy - int(mask.sum()) * math.log2(2 * math.e * math.radians(mpjae_deg))


def unidextok_point(model, data: HandStates, fit: HandStates | None = None, encoding: EncodingConfig | None = None) -> dict:
    """Nominal bits, measured rate (bits), entropy-coded bits (priors fitted on `fit`'s codes, when given) and MPJAE
    (deg) of `model` on `data` (one hand); `encoding` None = the model's own."""
    from lerobot_unidextok.evaluation import mpjae_deg, reconstruct

    cfg = model.config
    rec = reconstruct(model, data.states_rad, data.hands, allow_unknown=True, masks=data.masks, encoding=encoding)
    codes = rec.codes.reshape(len(data), -1)
    point = {
        "nominal_bits": cfg.num_tokens * cfg.num_groups * math.log2(cfg.codebook_size),
        "rate_bits": measured_rate_bits(codes),
        "mpjae_deg": mpjae_deg(rec.states_rad, data.states_rad, data.masks),
        "tokens": cfg.num_tokens * cfg.num_groups,
    }
    if fit is not None:
        fitted = reconstruct(model, fit.states_rad, fit.hands, allow_unknown=True, masks=fit.masks,
                             encoding=encoding).codes.reshape(len(fit), -1)  # fmt: skip
        point["coded_bits"] = coded_bits(fitted, codes, cfg.codebook_size)
    return point


def binning_point(data: HandStates, bits: int, fit: HandStates | None = None) -> dict:
    """Per-joint uniform binning at `bits` bits per active joint on `data` (one hand); entropy-coded bits with
    priors fitted on `fit`, when given."""
    from experiments.unseen_data import hand_binning
    from lerobot_unidextok.evaluation import mpjae_deg

    hand = _one_hand(data)
    binning = hand_binning(hand, 2**bits)
    codes = binning.encode(data.states_rad, hand)  # (M, active DoFs)
    pred = binning.decode(codes, hand).numpy()
    point = {
        "bits": bits,
        "nominal_bits": float(binning.rate(hand).bits_per_state),
        "rate_bits": measured_rate_bits(codes.numpy()),
        "mpjae_deg": mpjae_deg(pred, data.states_rad, data.masks),
    }
    if fit is not None:
        point["coded_bits"] = coded_bits(binning.encode(fit.states_rad, hand).numpy(), codes.numpy(), 2**bits)
    return point


def pca_curve(data: HandStates, fit: HandStates, max_bits: int) -> list[dict]:
    """A transform code of `data` (one hand): PCA of `fit`'s active DoFs (each scaled by the hand's registered
    range), every coefficient quantised with step 2^-b (b = 1..max_bits + 2 in quarters), entropy-coded with priors fitted on
    `fit`'s coefficients; per b the coded bits, MPJAE (deg) and the coefficients that take more than one value
    on `fit` (the tokens a prompt carries; the others decode to their constant) and the most bins one of them
    spans there (their vocabulary)."""
    from experiments.unseen_data import hand_binning
    from lerobot_unidextok.evaluation import mpjae_deg

    hand = _one_hand(data)
    rng = hand_binning(hand, 2).ranges[hand]
    mask = rng.active_mask
    scale = (rng.upper_rad - rng.lower_rad)[mask]  # (n,) radians per unit
    z_fit = fit.states_rad[:, mask] / scale  # (F, n)
    mean = z_fit.mean(0)
    _, _, basis = np.linalg.svd(z_fit - mean, full_matrices=False)  # (n, n) rows: principal directions
    c_fit, c = (z_fit - mean) @ basis.T, (data.states_rad[:, mask] / scale - mean) @ basis.T  # (F, n), (M, n)
    bound = np.abs(basis).sum(1)[None, :] / 2 + np.abs(np.concatenate([c_fit, c])).max(0, keepdims=True)  # (1, n)
    curve = []
    for quarter in range(4, 4 * (max_bits + 2) + 1):  # steps 2^-1 .. 2^-(max_bits + 2), four per octave
        b = quarter / 4
        step = 2.0**-b
        q_fit, q = np.round(c_fit / step), np.round(c / step)  # integer bins
        lo = -np.ceil(bound / step)  # (1, n) the alphabet covers every bin the data could reach
        pred = np.zeros_like(data.states_rad)
        pred[:, mask] = ((q * step) @ basis + mean) * scale
        curve.append({"bits": b, "coded_bits": coded_bits((q_fit - lo).astype(int), (q - lo).astype(int),
                                                          (1 - 2 * lo[0]).astype(int)),
                      "mpjae_deg": mpjae_deg(pred, data.states_rad, data.masks),
                      "tokens": int((np.ptp(q_fit, axis=0) > 0).sum()),
                      "vocabulary": int(np.ptp(q_fit, axis=0).max() + 1)})  # fmt: skip
    return curve


def equal_bits(unidextok: dict, curve: list[dict]) -> dict:
    """Binning (curve sorted by b) at the largest b whose nominal bits <= UniDexTok's measured rate, and at the
    smallest b whose MPJAE <= UniDexTok's; None where no b of the curve qualifies."""
    fits = [c for c in curve if c["nominal_bits"] <= unidextok["rate_bits"]]
    beats = [c for c in curve if c["mpjae_deg"] <= unidextok["mpjae_deg"]]
    return {"at_rate": fits[-1] if fits else None, "to_match": beats[0] if beats else None}


def _binning_at(row: dict, bits: int) -> dict | None:
    return next((c for c in row["binning"] if c["bits"] == bits), None)


def cheapest_within(curve: list[dict], mpjae_deg: float) -> dict | None:
    """The point of `curve` with the fewest coded bits whose MPJAE is at most `mpjae_deg` (None if none is)."""
    ok = [c for c in curve if c["mpjae_deg"] <= mpjae_deg]
    return min(ok, key=lambda c: c["coded_bits"]) if ok else None


def _one_hand(data: HandStates) -> str:
    names = data.hand_names()
    if len(names) != 1:
        raise ValueError(f"an evaluation set holds one hand, got {names}")
    return names[0]


# ---------------------------------------------------------------------------------------------
# evaluation sets and the run
# ---------------------------------------------------------------------------------------------
def evaluation_sets(cfg: RateDistortionConfig) -> dict[str, HandStates]:
    """{label: one hand's rows}: each dataset's test episodes per hand, then each hand's in-range states."""
    return test_and_range_sets(cfg.datasets, cfg.range_hands, cfg.range_rows, cfg.range_seed)


def test_and_range_sets(datasets: list[str], range_hands: list[str], range_rows: int,
                        range_seed: int) -> dict[str, HandStates]:  # fmt: skip
    """{label: one hand's rows}: each converted dataset's test episodes per hand, then `range_rows` states
    uniform inside each of `range_hands`' registered ranges (empty = every registered hand; 0 rows = none)."""
    from lerobot_unidextok import hands
    from lerobot_unidextok.training import load_hand_states
    from lerobot_unidextok.training.coverage import range_states

    sets = {}
    for root in datasets:
        if not Path(root).is_dir():
            raise FileNotFoundError(f"{root}: no converted dataset there; write it with `{DATA_COMMAND}` "
                                    "or pass --datasets='[<converted root>,...]'")  # fmt: skip
        data = load_hand_states([root], split="test")
        for hand in data.hand_names():
            sets[f"{Path(root).name} test episodes: {hand}"] = data.only(hand)
    if range_rows:
        for hand in range_hands or list(hands.names()):
            sets[f"in-range states: {hand}"] = range_states(hand, range_rows, range_seed)
    return sets


def fit_sets(cfg: RateDistortionConfig, sets: dict[str, HandStates]) -> dict[str, HandStates]:
    """{label: rows the entropy coders' priors of that set are fitted on}: the dataset's training-split rows of the
    hand for a test-episode set, `fit_rows` in-range states of seed `range_seed + 1` for an in-range set."""
    from lerobot_unidextok.training import load_hand_states
    from lerobot_unidextok.training.coverage import range_states

    train = {Path(root).name: load_hand_states([root], split="train") for root in cfg.datasets}
    out = {}
    for label, data in sets.items():
        hand = _one_hand(data)
        if " test episodes: " in label:
            out[label] = train[label.split(" test episodes: ")[0]].only(hand)
        else:
            out[label] = range_states(hand, cfg.fit_rows, cfg.range_seed + 1)
    return out


def checkpoint_about(checkpoint: str) -> dict:
    """The checkpoint as given and its training steps and chosen step (its folder's training_state.json), if any."""
    from lerobot_unidextok.pretrained import resolve

    folder = Path(resolve(checkpoint))
    state_file = folder / "training_state.json"
    state = json.loads(state_file.read_text()) if state_file.is_file() else {}
    return {"checkpoint": checkpoint, "steps": state.get("steps"), "best_step": state.get("step")}


def run(cfg: RateDistortionConfig) -> dict:
    from lerobot_unidextok.evaluation.report import encoding
    from lerobot_unidextok.tokenizer import UniDexTok

    t0 = time.time()
    model = UniDexTok.from_pretrained(cfg.checkpoint, encoding=cfg.encoding)
    rows = []
    sets = evaluation_sets(cfg)
    fits = fit_sets(cfg, sets)
    for label, data in sets.items():
        hand, fit = _one_hand(data), fits[label]
        udt = unidextok_point(model, data, fit)
        curve = [binning_point(data, b, fit) for b in range(1, cfg.max_bits + 1)]
        row = {"set": label, "hand": hand, "rows": len(data), "fit_rows": len(fit), "dofs": int(data.masks.any(0).sum()),
               "known_hand": model.knows_hand(hand), "unidextok": udt, "binning": curve,
               "equal_bits": equal_bits(udt, curve), "pca": pca_curve(data, fit, cfg.max_bits)}  # fmt: skip
        if model.config.encoding.rounds:
            row["unidextok_nearest"] = unidextok_point(model, data, fit, encoding=NEAREST_CODES)
        if "test episodes" not in label:
            row["slb"] = {"bits_at_8bit_binning": slb_bits(data, _binning_at(row, 8)["mpjae_deg"])
                          if _binning_at(row, 8) else None}  # fmt: skip
        rows.append(row)
    folder = Path(cfg.output_root) / NAME
    folder.mkdir(parents=True, exist_ok=True)
    png = plot(rows, folder / f"{NAME}.png")
    result = {"experiment": NAME, "command": command_line(cfg), "config": dataclasses.asdict(cfg),
              "tokenizer": {**checkpoint_about(cfg.checkpoint), "encoding": encoding(model.config)}, "rows": rows,
              "figures": {"rate_distortion": str(png)},
              "provenance": provenance(cfg, rows, time.time() - t0)}  # fmt: skip
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def command_line(cfg: RateDistortionConfig) -> str:
    """`python experiments/rate_distortion.py` with every flag that differs from the defaults."""
    flags = []
    for f in dataclasses.fields(cfg):
        value, default = getattr(cfg, f.name), getattr(RateDistortionConfig(), f.name)
        if value != default:
            flags.append(f"--{f.name}='[{','.join(map(str, value))}]'" if isinstance(value, list) else f"--{f.name}={value}")
    return " ".join(["python experiments/rate_distortion.py", *flags])


def provenance(cfg: RateDistortionConfig, rows: list[dict], seconds: float) -> dict:
    """What `make_results` prints above the tables (no training: the checkpoint instead of a preset)."""
    source = "real" if list(cfg.datasets) == list(DEFAULT_DATASETS) else "datasets"
    return {"data": {"source": source, "synthetic_sample": False, "datasets": list(cfg.datasets),
                     "test_rows": sum(r["rows"] for r in rows if "test episodes" in r["set"]),
                     "hands": sorted({r["hand"] for r in rows})},
            "checkpoint": checkpoint_about(cfg.checkpoint), "seed": cfg.range_seed, "git_commit": git_commit(),
            "config": dataclasses.asdict(cfg), "wall_seconds": round(seconds, 1),
            "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip


# ---------------------------------------------------------------------------------------------
# tables and figure
# ---------------------------------------------------------------------------------------------
def _binning_cell(c: dict | None, what: str) -> str:
    if c is None:
        return f"none at b <= {what}"
    return f"{c['bits']} ({c['nominal_bits']:.0f} bits): {c['mpjae_deg']:.3f}"


def summary_table(result: dict) -> str:
    """One row per set: UniDexTok's bits and MPJAE next to binning at equal bits."""
    max_bits = result["config"]["max_bits"]
    rows = []
    for r in result["rows"]:
        u, eq = r["unidextok"], r["equal_bits"]
        name = r["set"] if r["known_hand"] else f"{r['set']} (unknown hand)"
        rows.append([name, r["rows"], r["dofs"], f"{u['nominal_bits']:.0f}", f"{u['rate_bits']:.1f}",
                     f"{u['mpjae_deg']:.3f}", _binning_cell(eq["at_rate"], str(max_bits)),
                     _binning_cell(eq["to_match"], str(max_bits))])  # fmt: skip
    return md_table(["set", "rows", "DoFs", "UniDexTok nominal bits", "UniDexTok measured rate (bits)",
                     "UniDexTok MPJAE (deg)", f"binning, largest b <= {max_bits} within that rate: b (bits): MPJAE",
                     "binning, smallest b matching UniDexTok: b (bits): MPJAE"], rows)  # fmt: skip


def verdict(result: dict) -> str:
    """Over the sets: how many times fewer bits binning needs for UniDexTok's MPJAE, and how many times lower
    binning's MPJAE is within UniDexTok's measured rate."""
    rows, max_bits = result["rows"], result["config"]["max_bits"]
    match = [r for r in rows if r["equal_bits"]["to_match"]]
    within = [r for r in rows if r["equal_bits"]["at_rate"]]

    def span(values: list[float]) -> str:
        return f"{min(values):.1f}-{max(values):.1f}x"

    parts = []
    if match:
        need = [r["equal_bits"]["to_match"]["nominal_bits"] for r in match]
        parts.append(
            f"Binning reaches UniDexTok's MPJAE on {len(match)} of {len(rows)} sets with "
            f"{span([r['unidextok']['rate_bits'] / n for r, n in zip(match, need, strict=True)])} fewer bits than "
            f"UniDexTok's measured rate ({span([r['unidextok']['nominal_bits'] / n for r, n in zip(match, need, strict=True)])} "
            "fewer than its nominal bits)."
        )
    if len(match) < len(rows):
        parts.append(f"On {len(rows) - len(match)} of {len(rows)} sets binning needs more than b = {max_bits}.")
    if within:
        ratios = [r["unidextok"]["mpjae_deg"] / r["equal_bits"]["at_rate"]["mpjae_deg"] for r in within]
        ahead = sum(x > 1 for x in ratios)
        parts.append(f"Within UniDexTok's measured rate (b capped at {max_bits}), binning's MPJAE is lower on {ahead} "
                     f"of {len(within)} sets (UniDexTok's MPJAE over binning's: {min(ratios):.2f}-{max(ratios):.2f}; "
                     "below 1, UniDexTok is the more accurate).")
    return " ".join(parts)


def prompt_table(result: dict) -> str:
    """Per set: 8-bit binning's MPJAE and coded bits, the bound at that MPJAE (in-range sets), the fewest PCA and
    UniDexTok coded bits reaching it, and the tokens a prompt carries at that error."""
    rows = []
    for r in result["rows"]:
        ref = _binning_at(r, 8)
        if ref is None or "coded_bits" not in ref:
            continue
        target = ref["mpjae_deg"]
        pca = cheapest_within(r["pca"], target)
        udt = [(name, r[key]) for name, key in (("default", "unidextok"), ("nearest", "unidextok_nearest")) if key in r]
        reached = [(name, u) for name, u in udt if u["mpjae_deg"] <= target]
        best = min(reached, key=lambda nu: nu[1]["coded_bits"]) if reached else None
        slb = r.get("slb", {}).get("bits_at_8bit_binning")
        rows.append([r["set"], r["dofs"], f"{target:.3f}", f"{ref['coded_bits']:.1f}",
                     "-" if slb is None else f"{slb:.1f}",
                     f"{pca['coded_bits']:.1f} (step 2^-{pca['bits']:g})" if pca else "not reached",
                     f"{best[1]['coded_bits']:.1f} ({best[0]}, {best[1]['mpjae_deg']:.3f} deg)" if best
                     else "not reached (" + ", ".join(f"{n} {u['mpjae_deg']:.3f} deg" for n, u in udt) + ")",
                     f"{r['dofs']} x 256", f"{pca['tokens']} x {pca['vocabulary']}" if pca else "-",
                     f"{best[1]['tokens']} x {2 ** round(best[1]['nominal_bits'] / best[1]['tokens'])}" if best
                     else "-"])  # fmt: skip
    return md_table(["set", "DoFs", "8-bit binning MPJAE (deg)", "8-bit binning coded bits",
                     "lower bound at that MPJAE (bits)", "PCA coded bits at <= that MPJAE",
                     "UniDexTok coded bits at <= that MPJAE", "prompt tokens: binning",
                     "prompt tokens: PCA", "prompt tokens: UniDexTok"], rows)  # fmt: skip


def coded_verdict(result: dict) -> str:
    """At 8-bit binning's error, entropy-coded: on how many sets UniDexTok and PCA spend fewer bits than binning,
    and on the in-range sets how many bits any code could save at most (binning's bits over the bound)."""
    rows = [r for r in result["rows"] if (_binning_at(r, 8) or {}).get("coded_bits") is not None]
    if not rows:
        return ""
    udt_wins, pca_wins, slack, over = [], [], [], []
    for r in rows:
        ref = _binning_at(r, 8)
        for key in ("unidextok", "unidextok_nearest"):
            u = r.get(key)
            if u and u["mpjae_deg"] <= ref["mpjae_deg"]:
                over.append(u["coded_bits"] / ref["coded_bits"])
                if u["coded_bits"] < ref["coded_bits"]:
                    udt_wins.append(r["set"])
                break
        pca = cheapest_within(r["pca"], ref["mpjae_deg"])
        if pca and pca["coded_bits"] < ref["coded_bits"]:
            pca_wins.append(f"{r['set']} ({ref['coded_bits']:.1f} -> {pca['coded_bits']:.1f})")
        if r.get("slb", {}).get("bits_at_8bit_binning") is not None:
            slack.append((ref["coded_bits"] - r["slb"]["bits_at_8bit_binning"]) / r["dofs"])
    parts = [f"At 8-bit binning's error, UniDexTok's entropy-coded codes spend fewer bits than binning's on "
             f"{len(set(udt_wins))} of {len(rows)} sets" + (f" ({', '.join(sorted(set(udt_wins)))})" if udt_wins else "")
             + f"; the PCA code on {len(pca_wins)} of {len(rows)}" + (f": {'; '.join(pca_wins)}" if pca_wins else "") + "."]
    if over:
        parts.append(f"Where UniDexTok reaches that error ({len(over)} of {len(rows)} sets) its codes cost "
                     f"{min(over):.1f}-{max(over):.1f}x binning's bits.")
    if slack:
        parts.append(f"On the in-range states no code can save more than {min(slack):.2f}-{max(slack):.2f} bits per "
                     "active joint at that error: binning's bits over the Shannon lower bound.")
    return " ".join(parts)


def curve_table(result: dict, key: str, digits: int) -> str:
    bits = [c["bits"] for c in result["rows"][0]["binning"]] if result["rows"] else []
    rows = [[r["set"], *(f"{c[key]:.{digits}f}" for c in r["binning"])] for r in result["rows"]]
    return md_table(["set", *(f"b={b}" for b in bits)], rows)


def markdown(result: dict) -> str:
    tok = result["tokenizer"]
    trained = (f"{tok['steps']} training steps, checkpoint of step {tok['best_step']}" if tok.get("steps")
               else "no training_state.json")  # fmt: skip
    return "\n".join([
        f"# {NAME}", "",
        f"Tokenizer `{tok['checkpoint']}` ({trained}; encoding: {tok.get('encoding', 'nearest codes')}) against "
        "per-joint uniform binning over each hand's "
        "registered range at b bits per active joint, on each set's rows (one hand per set; test episodes never "
        f"trained on; in-range states: uniform inside the hand's registered ranges, seed {result['config']['range_seed']}). "
        "Nominal bits: UniDexTok N x K x log2(codebook size), binning b x DoFs. Measured rate: the sum over code "
        "positions of each position's empirical code entropy on the set (an upper bound of the codes' joint "
        "entropy, estimated from the set's rows: at most log2(rows) bits per position). MPJAE in degrees over "
        "active DoFs.", "",
        summary_table(result), "",
        verdict(result), "",
        *([
            "At 8-bit binning's error, entropy-coded (`coded_bits`: priors fitted on the dataset's training-split "
            f"rows, or on {result['config'].get('fit_rows', '-')} in-range states of seed "
            f"{result['config']['range_seed'] + 1}; the lower bound: the Shannon lower bound of in-range states, any "
            "code; prompt tokens: what a VLA prompt carries for one hand state at that error, count x vocabulary):",
            "", prompt_table(result), "", coded_verdict(result), "",
        ] if coded_verdict(result) else []),
        "Binning MPJAE (deg) at b bits per active joint:", "",
        curve_table(result, "mpjae_deg", 3), "",
        "Binning entropy-coded bits per state at b bits per active joint:", "",
        curve_table(result, "coded_bits", 1), "",
        "Binning measured rate (bits per state) at b bits per active joint:", "",
        curve_table(result, "rate_bits", 1),
    ])  # fmt: skip


def plot(rows: list[dict], out_path: Path) -> Path:
    """Bits per state (x, log2) vs MPJAE (y, log): binning curve per set, UniDexTok at nominal (hollow) and
    measured rate (filled); recorded test sets left, in-range states right."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    from lerobot_unidextok.viz.style import save

    panels = [("test episodes", [r for r in rows if "test episodes" in r["set"]]),
              ("in-range states", [r for r in rows if "test episodes" not in r["set"]])]  # fmt: skip
    panels = [(t, rs) for t, rs in panels if rs]
    fig = Figure(figsize=(6.2 * len(panels), 4.8))
    for i, (title, rs) in enumerate(panels):
        ax = fig.add_subplot(1, len(panels), i + 1)
        colors = [colormaps["tab20"](j % 20) for j in range(len(rs))]
        for r, color in zip(rs, colors, strict=True):
            curve, key = r["binning"], "coded_bits" if "coded_bits" in r["binning"][0] else "nominal_bits"
            ax.plot([c[key] for c in curve], [c["mpjae_deg"] for c in curve], "-", color=color,
                    lw=1.2, marker=".", label=r["set"].split(": ")[-1] if "in-range" in title else r["set"])  # fmt: skip
            if r.get("pca"):
                ax.plot([c["coded_bits"] for c in r["pca"]], [c["mpjae_deg"] for c in r["pca"]], "--", color=color,
                        lw=0.9)  # fmt: skip
            if r.get("slb", {}).get("bits_at_8bit_binning") is not None:
                ref = _binning_at(r, 8)
                ax.scatter([r["slb"]["bits_at_8bit_binning"]], [ref["mpjae_deg"]], color=color, marker="|", s=80)
            u = r["unidextok"]
            ax.scatter([u["nominal_bits"]], [u["mpjae_deg"]], facecolor="none", edgecolor=color, s=60, zorder=3)
            ax.scatter([u.get("coded_bits", u["rate_bits"])], [u["mpjae_deg"]], color=color, edgecolor="#222222",
                       marker="*", s=110, zorder=4)  # fmt: skip
            if "unidextok_nearest" in r:
                n = r["unidextok_nearest"]
                ax.scatter([n.get("coded_bits", n["rate_bits"])], [n["mpjae_deg"]], color=color, edgecolor="#222222",
                           marker="v", s=50, zorder=4)  # fmt: skip
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("entropy-coded bits per hand state (log2)")
        ax.set_ylabel("MPJAE (deg, log)")
        ax.set_title(f"{title}: binning (lines), PCA code (dashed), bound at 8-bit binning's error (|),\n"
                     "UniDexTok coded (* its encoding, v nearest codes; o 320 nominal bits)", fontsize=8)  # fmt: skip
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=6, frameon=False, ncol=2 if len(rs) > 8 else 1)
    return save(fig, out_path)


def parse(argv: list[str] | None = None) -> RateDistortionConfig:
    return runtime.parse(RateDistortionConfig, argv)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(RateDistortionConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
