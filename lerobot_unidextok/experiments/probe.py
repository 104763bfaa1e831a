"""Representation quality: linear probe and cosine k-NN (top-1 / top-3) on UniDexTok encoder embeddings
and on quantized features, for labelled gestures.

- Sample gestures: the sample generator's per-frame labels (`gestures.json`) on frames where the gesture is
  held, each hand's state = the generating UDHM angles as that hand records them (robots: through its spec's
  native units and back). Split by episode. Also cross-hand retrieval: human training frames as the gallery,
  robot held-out frames as queries.
- LinkerHand vendor presets (real, `preset_actions_en` of the LinkerHand GUI): gestures named alike across
  hand models; leave-one-hand-out nearest-neighbour retrieval. Skipped when the file is absent.
The input angles themselves are scored as a reference feature.
"""

import json
import logging
import time
from pathlib import Path

import numpy as np
import torch

from lerobot_unidextok.experiments.common import (
    HUMAN,
    load_data,
    md_table,
    out_dir,
    provenance,
    selection_split,
    trained_unidextok,
    write_result,
)
from lerobot_unidextok.experiments.config import ExperimentConfig, parse_config
from lerobot_unidextok.experiments.runtime import setup

logger = logging.getLogger(__name__)
NAME = "probe"
FEATURES = ("input angles", "encoder embedding", "quantized features")
LINKERHAND_MODELS = {
    "L10": "linkerhand_l10",
    "L20": "linkerhand_l20",
    "L6": "linkerhand_l6",
}
# vendor preset name -> shared gesture name (only names with one clear meaning across models)
PRESET_CANON = {"open": "open", "count_5": "open", "fist": "fist", "thumbs_up": "thumbs_up", "OK": "ok",
                "count_1": "count_1", "count_2": "count_2", "count_3": "count_3", "count_4": "count_4"}  # fmt: skip


# ---------------------------------------------------------------------------------------------
# features
# ---------------------------------------------------------------------------------------------
@torch.no_grad()
def features(model, states_rad: np.ndarray, hands: np.ndarray) -> dict[str, np.ndarray]:
    """(N, D) features per kind: input angles / pi, encoder output (B, N*C), quantized codes (B, N*C)."""
    model.eval()
    out = {k: [] for k in FEATURES}
    for i in range(0, len(states_rad), 2048):
        x = torch.as_tensor(states_rad[i : i + 2048], dtype=torch.float32)  # (B, 22)
        h = [str(s) for s in hands[i : i + 2048]]
        c = model.hand_embed(model.hand_ids(h, x.shape[0], allow_unknown=True))  # (B, C)
        z = model._encode_latent(x, c)  # (B, N, C)
        zq = model.quantizer.get_output_from_indices(model.encode(x, h, allow_unknown=True))  # (B, N, C)
        out["input angles"].append((x / np.pi).numpy())
        out["encoder embedding"].append(z.flatten(1).numpy())
        out["quantized features"].append(zq.flatten(1).numpy())
    return {k: np.concatenate(v).astype(np.float64) for k, v in out.items()}


def knn_topk(train_x: np.ndarray, train_y: np.ndarray, test_x: np.ndarray, test_y: np.ndarray) -> dict[str, float]:
    """Cosine nearest neighbours: top-1 = the nearest one's label is right; top-3 = the right label is among
    the 3 nearest neighbours' labels."""
    a = train_x / np.linalg.norm(train_x, axis=1, keepdims=True).clip(1e-12)
    b = test_x / np.linalg.norm(test_x, axis=1, keepdims=True).clip(1e-12)
    sim = b @ a.T  # (Q, G)
    k = min(3, sim.shape[1])
    nn = np.argsort(-sim, axis=1)[:, :k]  # (Q, k)
    labels = train_y[nn]
    return {
        "knn_top1": float((labels[:, 0] == test_y).mean()),
        "knn_top3": float((labels == test_y[:, None]).any(1).mean()),
    }


def linear_probe(
    train_x: np.ndarray,
    train_y: np.ndarray,
    test_x: np.ndarray,
    test_y: np.ndarray,
    seed: int,
) -> float:
    """Multinomial logistic regression (standardised features, L2 1e-3, L-BFGS); test accuracy."""
    classes = np.unique(train_y)
    idx = {c: i for i, c in enumerate(classes)}
    mu, sd = train_x.mean(0), train_x.std(0) + 1e-6
    xt = torch.as_tensor((train_x - mu) / sd, dtype=torch.float32)
    yt = torch.as_tensor([idx[c] for c in train_y])
    torch.manual_seed(seed)
    lin = torch.nn.Linear(xt.shape[1], len(classes))
    opt = torch.optim.LBFGS(
        lin.parameters(),
        lr=1.0,
        max_iter=200,
        history_size=20,
        line_search_fn="strong_wolfe",
    )

    def closure():
        opt.zero_grad()
        loss = torch.nn.functional.cross_entropy(lin(xt), yt) + 1e-3 * lin.weight.pow(2).sum()
        loss.backward()
        return loss

    opt.step(closure)
    with torch.no_grad():
        pred = lin(torch.as_tensor((test_x - mu) / sd, dtype=torch.float32)).argmax(1).numpy()
    return float((classes[pred] == test_y).mean())


# ---------------------------------------------------------------------------------------------
# labelled sets
# ---------------------------------------------------------------------------------------------
def _source_hand(source: str, entry: dict) -> str | None:
    """The hand spec of a sample episode (the bag samples name theirs in the labels file)."""
    from lerobot_unidextok.conversion import samples

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
    from lerobot_unidextok.conversion.samples import (
        LABELS_FILE,
        SAMPLE_SOURCES,
        TRUTH_FILE,
    )

    states, hands, labels, episodes = [], [], [], []
    for source in SAMPLE_SOURCES:
        folder = raw / source
        if not (folder / LABELS_FILE).is_file():
            continue
        eps = json.loads((folder / LABELS_FILE).read_text())["episodes"]
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
            f"no labelled sample frames under {raw}; the sample sources need {LABELS_FILE} and {TRUTH_FILE}"
        )
    out = {
        "states": np.concatenate(states),
        "hands": np.array(hands),
        "labels": np.array(labels),
        "episodes": np.array(episodes),
    }
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


def linkerhand_presets(path: Path) -> dict[str, np.ndarray] | None:
    """Vendor preset gestures named alike across LinkerHand models, as UDHM states (right hand)."""
    from lerobot_unidextok import hands as registry

    if not path.is_file():
        return None
    table = json.loads(path.read_text())
    states, hands, labels = [], [], []
    for model, hand in LINKERHAND_MODELS.items():
        presets = table.get(model, {}).get("preset_actions_en", {})
        spec = registry.get(hand)
        for name, raw in presets.items():
            if name in PRESET_CANON and len(raw) == spec.num_native:
                states.append(np.asarray(spec.to_udhm(np.asarray(raw, np.float64), "right", on_out_of_range="clip")))
                hands.append(hand)
                labels.append(PRESET_CANON[name])
    labels_arr, hands_arr = np.array(labels), np.array(hands)
    shared = [lab for lab in np.unique(labels_arr) if len(np.unique(hands_arr[labels_arr == lab])) >= 2]
    keep = np.isin(labels_arr, shared)
    return {
        "states": np.stack(states)[keep],
        "hands": hands_arr[keep],
        "labels": labels_arr[keep],
    }


# ---------------------------------------------------------------------------------------------
# experiment
# ---------------------------------------------------------------------------------------------
def run(cfg: ExperimentConfig) -> dict:
    t0 = time.perf_counter()
    folder = out_dir(cfg, NAME)
    data = load_data(cfg)
    fit, select = selection_split(data.train, cfg.seed)
    model, train_info = trained_unidextok(cfg, "all_hands", fit, select)
    result = {
        "experiment": NAME,
        "provenance": provenance(cfg, data, 0.0),
        "training": train_info,
        "figures": {},
    }

    if data.raw_dir is not None:
        g = sample_gestures(data.raw_dir, cfg.probe_max_per_class, cfg.seed)
        test = episode_split(g["episodes"], cfg.seed)
        feats = features(model, g["states"], g["hands"])
        robot_q = test & (g["hands"] != HUMAN)
        human_g = ~test & (g["hands"] == HUMAN)
        robot_q &= np.isin(g["labels"], g["labels"][human_g])  # only gestures the human gallery contains
        rows = []
        for kind, x in feats.items():
            row = {"feature": kind, "linear_probe": linear_probe(x[~test], g["labels"][~test], x[test], g["labels"][test], cfg.seed),
                   **knn_topk(x[~test], g["labels"][~test], x[test], g["labels"][test])}  # fmt: skip
            if robot_q.any() and human_g.any():
                cross = knn_topk(x[human_g], g["labels"][human_g], x[robot_q], g["labels"][robot_q])
                row.update(
                    {
                        "human_to_robot_top1": cross["knn_top1"],
                        "human_to_robot_top3": cross["knn_top3"],
                    }
                )
            rows.append(row)
        result["sample_gestures"] = {"rows": rows, "classes": sorted(set(g["labels"].tolist())), "train_frames": int((~test).sum()),
                                     "test_frames": int(test.sum()), "hands": sorted(set(g["hands"].tolist())),
                                     "chance": 1.0 / len(set(g["labels"].tolist()))}  # fmt: skip
    else:
        result["sample_gestures"] = None
        logger.info("user datasets carry no gesture labels: sample-gesture probe skipped")

    presets = linkerhand_presets(Path(cfg.linkerhand_presets))
    if presets is None or len(presets["labels"]) == 0:
        result["linkerhand_presets"] = None
        logger.info(
            "LinkerHand preset file absent (%s): real preset probe skipped",
            cfg.linkerhand_presets,
        )
    else:
        feats = features(model, presets["states"], presets["hands"])
        rows = []
        for kind, x in feats.items():
            hits1, hits3 = [], []
            for hand in np.unique(presets["hands"]):  # leave one hand out: gallery = the other models
                q, gal = presets["hands"] == hand, presets["hands"] != hand
                r = knn_topk(x[gal], presets["labels"][gal], x[q], presets["labels"][q])
                hits1.append(r["knn_top1"] * q.sum())
                hits3.append(r["knn_top3"] * q.sum())
            n = len(presets["labels"])
            rows.append(
                {
                    "feature": kind,
                    "knn_top1": sum(hits1) / n,
                    "knn_top3": sum(hits3) / n,
                }
            )
        result["linkerhand_presets"] = {"rows": rows, "presets": len(presets["labels"]), "classes": sorted(set(presets["labels"].tolist())),
                                        "hands": sorted(set(presets["hands"].tolist())),
                                        "hands_unseen_in_training": sorted(h for h in set(presets["hands"].tolist()) if not model.knows_hand(h)),
                                        "source": cfg.linkerhand_presets}  # fmt: skip
    result["provenance"]["wall_seconds"] = round(time.perf_counter() - t0, 1)
    write_result(folder, NAME, result, markdown(result))
    return result


def markdown(result: dict) -> str:
    lines = [f"# {NAME}", ""]
    sg = result.get("sample_gestures")
    if sg:
        lines += [(f"Sample gestures (SYNTHETIC generator labels): {len(sg['classes'])} classes (chance {sg['chance']:.2f}), "
                  f"{sg['train_frames']} train / {sg['test_frames']} test held frames split by episode, hands {', '.join(sg['hands'])}. "
                  "Human->robot: gallery = human training frames, queries = robot test frames of gestures the gallery has."), ""]  # fmt: skip
        lines.append(md_table(["feature", "linear probe acc", "k-NN top-1", "k-NN top-3", "human->robot top-1", "human->robot top-3"],
                              [[r["feature"], r["linear_probe"], r["knn_top1"], r["knn_top3"], r.get("human_to_robot_top1"),
                                r.get("human_to_robot_top3")] for r in sg["rows"]]))  # fmt: skip
    else:
        lines.append("Sample-gesture probe skipped (user datasets carry no gesture labels).")
    lp = result.get("linkerhand_presets")
    lines.append("")
    if lp:
        lines += [(f"LinkerHand vendor presets (real): {lp['presets']} presets of {len(lp['classes'])} shared gestures on "
                  f"{', '.join(lp['hands'])} (unseen in training: {', '.join(lp['hands_unseen_in_training']) or 'none'}); "
                  "leave-one-hand-out cosine nearest neighbour."), ""]  # fmt: skip
        lines.append(
            md_table(
                ["feature", "k-NN top-1", "k-NN top-3"],
                [[r["feature"], r["knn_top1"], r["knn_top3"]] for r in lp["rows"]],
            )
        )
    else:
        lines.append("LinkerHand vendor presets absent: skipped.")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    print(markdown(run(setup(parse_config(argv, __doc__)))))


if __name__ == "__main__":
    main()
