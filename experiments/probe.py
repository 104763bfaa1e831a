"""Representation probe as in the paper: cosine k-NN with majority vote (k = 1, 3) and a linear probe, on
UniDexTok and UniHM features (continuous encoder output and quantised features; the input angles as a
reference), for labelled gestures.

- LinkerHand vendor presets (real, `preset_actions_en` of the LinkerHand GUI, ../shared/data/real/
  linkerhand-ros2-sdk): gestures named alike across hand models; leave one hand model out (gallery and
  linear-probe training set = the other models' presets, queries = the held-out model's presets).
- Real human gestures (MediaPipe HandLandmarker world landmarks of real photos, ../shared/data/real/mediapipe):
  fist, pointing up (= count_1), thumb up (= thumbs_up), victory (= count_2), mapped to UDHM by the human
  spec; queries against the robot presets (gallery / probe training set): cross-embodiment retrieval. With
  6 results of 4 gestures (two are rotated copies of the same photo) a human-only split would be trivial.
- Sample gestures (SYNTHETIC data only): the generator's per-frame labels on held frames, split by episode.
Every feature is computed on the same rows: hands every probed model can embed (UniHM knows only the hands
it trained on; UniDexTok codes unseen hands through its unknown-hand embedding).
"""

import json
import logging
import time
from pathlib import Path

import numpy as np
import torch

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import baselines as B
from experiments.common import (
    HUMAN,
    load_data,
    md_table,
    out_dir,
    provenance,
    selection_split,
    trained_unidextok,
    write_result,
)
from experiments.config import ExperimentConfig, parse_config
from experiments.retargeted import retargeted_pairs
from experiments.runtime import setup

logger = logging.getLogger(__name__)
NAME = "probe"
INPUT = "input angles (reference)"
LINKERHAND_MODELS = {"L10": "linkerhand_l10", "L20": "linkerhand_l20", "L6": "linkerhand_l6"}
# vendor preset name -> shared gesture name (only names with one clear meaning across models)
PRESET_CANON = {"open": "open", "count_5": "open", "fist": "fist", "thumbs_up": "thumbs_up", "OK": "ok",
                "count_1": "count_1", "count_2": "count_2", "count_3": "count_3", "count_4": "count_4"}  # fmt: skip
# MediaPipe test gesture -> the same gesture among the vendor presets
HUMAN_GESTURE_CANON = {"fist": "fist", "pointing_up": "count_1", "thumb_up": "thumbs_up", "victory": "count_2"}


# ---------------------------------------------------------------------------------------------
# features
# ---------------------------------------------------------------------------------------------
@torch.no_grad()
def unidextok_features(model, states_rad: np.ndarray, hands: np.ndarray) -> dict[str, np.ndarray]:
    """UniDexTok encoder output `embed()` (B, N*C) and its quantised features (B, N*C)."""
    model.eval()
    enc, quant = [], []
    for i in range(0, len(states_rad), 2048):
        x = torch.as_tensor(states_rad[i : i + 2048], dtype=torch.float32)  # (B, 22)
        h = [str(s) for s in hands[i : i + 2048]]
        enc.append(model.embed(x, h, allow_unknown=True).flatten(1).numpy())  # (B, N*C)
        zq = model.quantizer.get_output_from_indices(model.encode(x, h, allow_unknown=True))  # (B, N, C)
        quant.append(zq.flatten(1).numpy())
    return {"UniDexTok encoder": np.concatenate(enc), "UniDexTok quantized": np.concatenate(quant)}


@torch.no_grad()
def unihm_features(tok, states_rad: np.ndarray, hands: np.ndarray) -> dict[str, np.ndarray]:
    """UniHM pre-quantisation latent `embed()` (B, D) and its codebook vector (B, D), per hand's encoder."""
    enc = np.zeros((len(states_rad), tok.config.embedding_dim))
    quant = np.zeros_like(enc)
    for hand in np.unique(hands):
        rows = hands == hand
        z = tok.embed(states_rad[rows], str(hand))  # (n, D)
        enc[rows] = z.numpy()
        quant[rows] = tok.quantizer.codebook(tok.quantizer.indices(z)).numpy()
    return {"UniHM encoder": enc, "UniHM quantized": quant}


def all_features(model, unihm, states_rad: np.ndarray, hands: np.ndarray) -> dict[str, np.ndarray]:
    feats = {INPUT: states_rad / np.pi, **unidextok_features(model, states_rad, hands)}
    if unihm is not None:
        feats.update(unihm_features(unihm, states_rad, hands))
    return {k: v.astype(np.float64) for k, v in feats.items()}


# ---------------------------------------------------------------------------------------------
# probes
# ---------------------------------------------------------------------------------------------
def knn_majority(train_x: np.ndarray, train_y: np.ndarray, test_x: np.ndarray, k: int) -> np.ndarray:
    """Cosine k-NN: the label most frequent among the k nearest training rows; a tie goes to the tied label
    of the nearest neighbour. Returns the predicted labels (Q,)."""
    a = train_x / np.linalg.norm(train_x, axis=1, keepdims=True).clip(1e-12)
    b = test_x / np.linalg.norm(test_x, axis=1, keepdims=True).clip(1e-12)
    order = np.argsort(-(b @ a.T), axis=1, kind="stable")[:, : min(k, len(train_x))]  # (Q, k) nearest first
    out = []
    for labels in train_y[order]:
        values, counts = np.unique(labels, return_counts=True)
        top = set(values[counts == counts.max()].tolist())
        out.append(next(lab for lab in labels if lab in top))  # nearest among the tied labels
    return np.array(out)


def linear_probe(train_x: np.ndarray, train_y: np.ndarray, test_x: np.ndarray, seed: int) -> np.ndarray:
    """Multinomial logistic regression (standardised features, L2 1e-3, L-BFGS); predicted test labels."""
    classes = np.unique(train_y)
    idx = {c: i for i, c in enumerate(classes)}
    mu, sd = train_x.mean(0), train_x.std(0) + 1e-6
    xt = torch.as_tensor((train_x - mu) / sd, dtype=torch.float32)
    yt = torch.as_tensor([idx[c] for c in train_y])
    torch.manual_seed(seed)
    lin = torch.nn.Linear(xt.shape[1], len(classes))
    opt = torch.optim.LBFGS(lin.parameters(), lr=1.0, max_iter=200, history_size=20, line_search_fn="strong_wolfe")

    def closure():
        opt.zero_grad()
        loss = torch.nn.functional.cross_entropy(lin(xt), yt) + 1e-3 * lin.weight.pow(2).sum()
        loss.backward()
        return loss

    opt.step(closure)
    with torch.no_grad():
        pred = lin(torch.as_tensor((test_x - mu) / sd, dtype=torch.float32)).argmax(1).numpy()
    return classes[pred]


def probe_scores(train_x, train_y, test_x, test_y, seed: int) -> dict[str, float]:
    """Accuracy of k-NN majority vote (k = 1, 3) and of the linear probe."""
    return {
        "knn1": float((knn_majority(train_x, train_y, test_x, 1) == test_y).mean()),
        "knn3": float((knn_majority(train_x, train_y, test_x, 3) == test_y).mean()),
        "linear": float((linear_probe(train_x, train_y, test_x, seed) == test_y).mean()),
    }


def leave_one_hand_out(feats: dict[str, np.ndarray], labels: np.ndarray, hands: np.ndarray, seed: int) -> list[dict]:
    """Per feature: queries = one hand's rows, gallery / probe training = the other hands' rows; pooled accuracy."""
    rows = []
    for kind, x in feats.items():
        hits = {"knn1": 0.0, "knn3": 0.0, "linear": 0.0}
        for hand in np.unique(hands):
            q, gal = hands == hand, hands != hand
            s = probe_scores(x[gal], labels[gal], x[q], labels[q], seed)
            for key in hits:
                hits[key] += s[key] * q.sum()
        rows.append({"feature": kind, **{k: v / len(labels) for k, v in hits.items()}})
    return rows


# ---------------------------------------------------------------------------------------------
# labelled sets
# ---------------------------------------------------------------------------------------------
def linkerhand_presets(path: Path, models: dict[str, str] = LINKERHAND_MODELS) -> dict[str, np.ndarray] | None:
    """Vendor preset gestures named alike across LinkerHand models, as UDHM states (right hand)."""
    from lerobot_unidextok import hands as registry

    if not path.is_file():
        return None
    table = json.loads(path.read_text())
    states, hands, labels = [], [], []
    for model, hand in models.items():
        presets = table.get(model, {}).get("preset_actions_en", {})
        spec = registry.get(hand)
        for name, raw in presets.items():
            if name in PRESET_CANON and len(raw) == spec.num_native:
                states.append(np.asarray(spec.to_udhm(np.asarray(raw, np.float64), "right", on_out_of_range="clip")))
                hands.append(hand)
                labels.append(PRESET_CANON[name])
    if not states:
        return None
    labels_arr, hands_arr = np.array(labels), np.array(hands)
    shared = [lab for lab in np.unique(labels_arr) if len(np.unique(hands_arr[labels_arr == lab])) >= 2]
    keep = np.isin(labels_arr, shared)
    return {"states": np.stack(states)[keep], "hands": hands_arr[keep], "labels": labels_arr[keep]}


def human_gestures(path: Path) -> dict[str, np.ndarray] | None:
    """MediaPipe world landmarks of real photos (right hands) with their gesture, as human UDHM states."""
    from lerobot_unidextok import hands as registry

    if not path.is_file():
        return None
    table = json.loads(path.read_text())
    kps, labels, names = [], [], []
    for name, entry in table.items():
        if isinstance(entry, dict) and entry.get("gesture") in HUMAN_GESTURE_CANON and entry.get("world_landmarks_m"):
            kps.append(np.asarray(entry["world_landmarks_m"], np.float64))  # (21, 3) m
            labels.append(HUMAN_GESTURE_CANON[entry["gesture"]])
            names.append(name)
    if not kps:
        return None
    states = np.asarray(registry.get(HUMAN).to_udhm(np.stack(kps), "right"))  # (M, 22) rad
    return {
        "states": states,
        "hands": np.full(len(states), HUMAN),
        "labels": np.array(labels),
        "names": np.array(names),
    }


def _source_hand(source: str, entry: dict) -> str | None:
    """The hand spec of a sample episode (the bag samples name theirs in the labels file)."""
    from lerobot_unidextok.samples import formats as samples

    if source in ("dexycb", "egodex"):
        return HUMAN
    if source == "let":
        return entry.get("hand", samples.HAND_LET)
    if source == "linkerhand":
        return samples.HAND_LINKERHAND.get(entry.get("hand_model"))
    return {"dexora": samples.HAND_DEXORA, "lerobot": samples.HAND_G1}.get(source)


def sample_gestures(raw: Path, max_per_class: int, seed: int) -> dict[str, np.ndarray]:
    """Held gesture frames of every sample source: states (N, 22) rad, hands, labels, episode ids."""
    from lerobot_unidextok import hands as registry
    from lerobot_unidextok.constants import SAMPLE_LABELS_FILE
    from lerobot_unidextok.samples import SAMPLE_SOURCES, TRUTH_FILE

    states, hands, labels, episodes = [], [], [], []
    for source in SAMPLE_SOURCES:
        folder = raw / source
        if not (folder / SAMPLE_LABELS_FILE).is_file():
            continue
        eps = json.loads((folder / SAMPLE_LABELS_FILE).read_text())["episodes"]
        truth = np.load(folder / TRUTH_FILE)
        for key, entry in eps.items():
            hand = _source_hand(source, entry)
            if hand is None:
                continue
            for side in ("left", "right"):
                if side not in entry or f"{key}|{side}" not in truth:
                    continue
                q = truth[f"{key}|{side}"].astype(np.float64)  # (T, 22) rad
                held = np.array(entry[f"{side}_holding"], bool) & (np.array(entry[side]) != "")
                if not held.any():
                    continue
                if hand != HUMAN:  # the gesture as this robot records it
                    spec = registry.get(hand)
                    q = np.asarray(spec.to_udhm(spec.from_udhm(q, side), side, on_out_of_range="clip"))
                states.append(q[held])
                hands += [hand] * int(held.sum())
                labels += [lab for lab, h in zip(entry[side], held, strict=True) if h]
                episodes += [f"{source}/{key}"] * int(held.sum())
    if not states:
        raise ValueError(
            f"no labelled sample frames under {raw}; the sample sources need {SAMPLE_LABELS_FILE} and {TRUTH_FILE}"
        )
    out = {"states": np.concatenate(states), "hands": np.array(hands), "labels": np.array(labels),
           "episodes": np.array(episodes)}  # fmt: skip
    rng = np.random.default_rng(seed)
    keep = []
    for lab in np.unique(out["labels"]):
        for hand in np.unique(out["hands"]):
            rows = np.flatnonzero((out["labels"] == lab) & (out["hands"] == hand))
            keep.append(rng.choice(rows, size=min(max_per_class, len(rows)), replace=False))
    keep = np.sort(np.concatenate(keep))
    return {k: v[keep] for k, v in out.items()}


def episode_split(episodes: np.ndarray, seed: int, test_fraction: float = 0.3) -> np.ndarray:
    """Boolean test mask: whole episodes, ~30 % of them."""
    uniq = np.unique(episodes)
    rng = np.random.default_rng(seed)
    test_eps = rng.choice(uniq, size=max(1, round(test_fraction * len(uniq))), replace=False)
    return np.isin(episodes, test_eps)


def _embeddable(unihm, hands: np.ndarray) -> np.ndarray:
    """Rows whose hand UniHM can embed (it knows only its training hands); all rows without UniHM."""
    if unihm is None:
        return np.ones(len(hands), dtype=bool)
    return np.isin(hands, sorted(unihm.decoders.keys()))


# ---------------------------------------------------------------------------------------------
# experiment
# ---------------------------------------------------------------------------------------------
def run(cfg: ExperimentConfig) -> dict:
    t0 = time.perf_counter()
    folder = out_dir(cfg, NAME)
    data = load_data(cfg)
    fit, select = selection_split(data.train, cfg.seed)
    model, train_info = trained_unidextok(cfg, "all_hands", fit, select)
    pairs = retargeted_pairs(cfg, data)
    unihm, unihm_name = B.unihm_for(cfg, fit, pairs)
    result = {"experiment": NAME, "provenance": provenance(cfg, data, 0.0), "training": train_info,
              "unihm": {"name": unihm_name, "hands": sorted(unihm.decoders.keys())}, "figures": {}}  # fmt: skip

    presets = linkerhand_presets(cfg.linkerhand_presets_path)
    if presets is not None:
        keep = _embeddable(unihm, presets["hands"])
        dropped = sorted(set(presets["hands"][~keep].tolist()))
        presets = {k: v[keep] for k, v in presets.items()} if keep.any() else None
    if presets is None or len(np.unique(presets["hands"])) < 2:
        result["linkerhand_presets"] = None
        logger.info("LinkerHand presets absent or on < 2 hands UniHM knows (%s): skipped", cfg.linkerhand_presets_path)
    else:
        feats = all_features(model, unihm, presets["states"], presets["hands"])
        result["linkerhand_presets"] = {
            "rows": leave_one_hand_out(feats, presets["labels"], presets["hands"], cfg.seed),
            "presets": len(presets["labels"]), "classes": sorted(set(presets["labels"].tolist())),
            "hands": sorted(set(presets["hands"].tolist())), "dropped_hands": dropped,
            "hands_unseen_by_unidextok": sorted(h for h in set(presets["hands"].tolist()) if not model.knows_hand(h)),
            "source": "linkerhand-ros2-sdk/linkerhand_gui_preset_actions.json",
        }  # fmt: skip

    human = human_gestures(cfg.human_gestures_path)
    if human is None or presets is None:
        result["human_gestures"] = None
        logger.info(
            "real human gestures or robot presets absent (%s): cross-embodiment probe skipped", cfg.human_gestures_path
        )
    else:
        gallery = np.isin(presets["labels"], human["labels"])
        states = np.concatenate([presets["states"][gallery], human["states"]])
        hands = np.concatenate([presets["hands"][gallery], human["hands"]])
        labels = np.concatenate([presets["labels"][gallery], human["labels"]])
        is_q = hands == HUMAN
        feats = all_features(model, unihm, states, hands)
        rows = [{"feature": kind, **probe_scores(x[~is_q], labels[~is_q], x[is_q], labels[is_q], cfg.seed)}
                for kind, x in feats.items()]  # fmt: skip
        result["human_gestures"] = {"rows": rows, "queries": int(is_q.sum()), "gallery": int((~is_q).sum()),
                                    "classes": sorted(set(human["labels"].tolist())), "files": human["names"].tolist(),
                                    "source": "mediapipe/mediapipe_hand_fixtures.json"}  # fmt: skip

    if data.raw_dir is not None:
        g = sample_gestures(data.raw_dir, cfg.probe_max_per_class, cfg.seed)
        keep = _embeddable(unihm, g["hands"])
        g = {k: v[keep] for k, v in g.items()}
        test = episode_split(g["episodes"], cfg.seed)
        feats = all_features(model, unihm, g["states"], g["hands"])
        rows = [{"feature": kind, **probe_scores(x[~test], g["labels"][~test], x[test], g["labels"][test], cfg.seed)}
                for kind, x in feats.items()]  # fmt: skip
        result["sample_gestures"] = {"rows": rows, "classes": sorted(set(g["labels"].tolist())), "train_frames": int((~test).sum()),
                                     "test_frames": int(test.sum()), "hands": sorted(set(g["hands"].tolist())),
                                     "chance": 1.0 / len(set(g["labels"].tolist()))}  # fmt: skip
    else:
        result["sample_gestures"] = None
    result["provenance"]["wall_seconds"] = round(time.perf_counter() - t0, 1)
    write_result(folder, NAME, result, markdown(result))
    return result


def _table(rows: list[dict]) -> str:
    return md_table(["feature", "k-NN k=1 (majority)", "k-NN k=3 (majority)", "linear probe"],
                    [[r["feature"], r["knn1"], r["knn3"], r["linear"]] for r in rows])  # fmt: skip


def markdown(result: dict) -> str:
    u = result.get("unihm", {})
    lines = [f"# {NAME}", "", ("Accuracy of cosine k-NN with majority vote (k = 1, 3; a tie goes to the nearest "
             f"neighbour's label) and of a linear probe (multinomial logistic regression), on UniDexTok and {u.get('name', 'UniHM')} "
             f"features (UniHM trained on: {', '.join(u.get('hands', []))}); the input angles / pi as a reference."), ""]  # fmt: skip
    lp = result.get("linkerhand_presets")
    if lp:
        lines += [(f"LinkerHand vendor presets (real): {lp['presets']} presets of {len(lp['classes'])} shared gestures "
                   f"({', '.join(lp['classes'])}) on {', '.join(lp['hands'])} (not embeddable by UniHM, left out: "
                   f"{', '.join(lp['dropped_hands']) or 'none'}; unseen by UniDexTok: {', '.join(lp['hands_unseen_by_unidextok']) or 'none'}); "
                   "leave one hand model out."), "", _table(lp["rows"]), ""]  # fmt: skip
    else:
        lines += ["LinkerHand vendor presets absent: skipped.", ""]
    hg = result.get("human_gestures")
    if hg:
        lines += [(f"Real human gestures (MediaPipe world landmarks of real photos, UDHM by IK): {hg['queries']} queries "
                   f"({', '.join(hg['classes'])}) against {hg['gallery']} LinkerHand presets of those gestures "
                   "(gallery and probe training set): cross-embodiment."), "", _table(hg["rows"]), ""]  # fmt: skip
    else:
        lines += ["Real human gestures: skipped (files absent).", ""]
    sg = result.get("sample_gestures")
    if sg:
        lines += [(f"Sample gestures (SYNTHETIC generator labels): {len(sg['classes'])} classes (chance {sg['chance']:.2f}), "
                   f"{sg['train_frames']} train / {sg['test_frames']} test held frames split by episode, hands "
                   f"{', '.join(sg['hands'])}."), "", _table(sg["rows"])]  # fmt: skip
    return "\n".join(lines).rstrip()


def main(argv: list[str] | None = None) -> None:
    print(markdown(run(setup(parse_config(argv)))))


if __name__ == "__main__":
    main()
