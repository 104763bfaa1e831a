"""One picture of every simulated hand at its power grasp and its press posture (MuJoCo, software rendering).

    MUJOCO_GL=egl .venv/bin/python tools/sim/render_hands.py --out docs/images/sim_hands.png

Each embodiment once (the two Inspire specs share a model): the hand on the simulator's wrist, level, as the
experts hold it, at `power` (left) and `press_index` (right) of its `SimHand.posture`, the table hidden. Hands come
from `sim_hands.sim_hand_names()`: the model files', the shipped built models and any URDF found under
`$UNIDEXTOK_URDF_DIR`. The image is quantised to 64 colours to stay small. EGL and OSMesa both render on a CPU
(llvmpipe); without either, `mujoco.Renderer` fails and so does this script.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image, ImageDraw  # noqa: E402

from lerobot_env_unidextok import sim_hands  # noqa: E402
from lerobot_env_unidextok.scene import Scene, base_spec  # noqa: E402

TILE = (240, 180)  # width, height of one posture's view (px)
PER_ROW = 3  # hands per row
POSTURES = ("power", "press_index")


def render_hand(name: str, renderer_cache: dict) -> Image.Image:
    """The hand `name` at POSTURES, side by side, its name written on top."""
    hand = sim_hands.load(name)
    scene = Scene.compile(base_spec(hand), hand)
    m, d = scene.model, mujoco.MjData(scene.model)
    m.geom_rgba[m.geom("table").id, 3] = 0.0
    renderer = mujoco.Renderer(m, TILE[1], TILE[0])
    renderer_cache[name] = renderer
    hand_geoms = [g for g in range(m.ngeom) if m.body(int(m.geom_bodyid[g])).name.startswith("hand/")]
    views = []
    for posture in POSTURES:
        d.qpos[:] = m.qpos0
        d.qpos[scene.wrist_qpos] = Scene.wrist_pose_to_joints(np.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0]))
        scene.place_hand(d, hand.posture(posture))
        mujoco.mj_forward(m, d)
        pts = d.geom_xpos[hand_geoms]
        cam = mujoco.MjvCamera()
        cam.lookat[:] = pts.mean(0)
        cam.distance = 2.2 * float(np.linalg.norm(pts - pts.mean(0), axis=1).max()) + 0.05
        cam.azimuth, cam.elevation = 215.0, -25.0
        renderer.update_scene(d, cam)
        views.append(renderer.render())
    tile = Image.fromarray(np.concatenate(views, axis=1))
    ImageDraw.Draw(tile).text((6, 4), f"{name}: {' | '.join(POSTURES)}", fill=(255, 255, 255))
    renderer.close()
    return tile


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("docs/images/sim_hands.png"))
    args = ap.parse_args()
    seen, names = set(), []
    for name in sim_hands.sim_hand_names():
        embodiment = sim_hands.load(name).spec.embodiment
        if embodiment not in seen:
            seen.add(embodiment)
            names.append(name)
    tiles = [render_hand(n, {}) for n in names]
    rows = -(-len(tiles) // PER_ROW)
    sheet = Image.new("RGB", (PER_ROW * 2 * TILE[0], rows * TILE[1]))
    for i, tile in enumerate(tiles):
        sheet.paste(tile, ((i % PER_ROW) * 2 * TILE[0], (i // PER_ROW) * TILE[1]))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.quantize(colors=64).save(args.out, optimize=True)
    print(f"wrote {args.out} ({len(names)} hands, {args.out.stat().st_size // 1024} kB)")


if __name__ == "__main__":
    main()
