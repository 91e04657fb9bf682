#!/usr/bin/env python3
"""sparseloop from Python, notebook style: render a drifting drone flight with the CLI, close its
loops with sparseloop.LoopClosing, evaluate before and after.

    PYTHONPATH=build/python /usr/bin/python3 examples/python_quickstart.py [SEQUENCE_DIR]

Without SEQUENCE_DIR it renders the default (60 frames, two laps, about 4 s) with build/bin/sparseloop
into a temporary folder. Cells are separated by '# %%' (VS Code / Jupytext run them one by one).
"""
# %% Imports and the sequence
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

import sparseloop

repo = pathlib.Path(__file__).resolve().parents[1]
if len(sys.argv) > 1:
    seq = pathlib.Path(sys.argv[1])
else:
    seq = pathlib.Path(tempfile.mkdtemp(prefix="sparseloop_quickstart_"))
    cli = os.environ.get("SPARSELOOP_CLI", str(repo / "build" / "bin" / "sparseloop"))
    subprocess.run([cli, "render", "--world", "aerial", "--plan", "circuit", "--frames", "60",
                    "--laps", "2", "--seed", "1", "--out", str(seq)], check=True,
                   stdout=subprocess.DEVNULL)

# %% The KITTI-layout folder: intrinsics, times, raw vSLAM poses (with drift), mapped pixels
p0 = [float(v) for v in (seq / "calib.txt").read_text().splitlines()[0].split()[1:]]
intrinsics = (p0[0], p0[5], p0[2], p0[6])  # fx, fy, cx, cy
times = [float(t) for t in (seq / "times.txt").read_text().split()]
raw = sparseloop.read_trajectory(str(seq / "poses_raw.txt"))  # dict; raw["poses"]: (N, 4, 4)
print(f"{len(times)} frames, intrinsics {intrinsics}")

# %% Online loop closing: one keyframe at a time, as a vSLAM would push them
closing = sparseloop.LoopClosing(
    config={"optimizer": {"rejection": "pcm"}},  # any `sparseloop config --dump` key
    on_correction=lambda c: print(f"  solve {c['revision']}: {c['num_loops']} loops"))
for i, t in enumerate(times):
    pixels, depths = sparseloop.read_mapped_pixels(str(seq / "mapped" / f"{i:06d}.txt"))
    event = closing.add_keyframe(
        id=i, timestamp=t, image=sparseloop.read_image(str(seq / "image_0" / f"{i:06d}.png")),
        intrinsics=intrinsics, pose=raw["poses"][i], mapped_pixels=pixels, mapped_depths=depths)
    if event["detected"]:
        print(f"loop {event['query_id']} -> {event['match_id']} ({event['inliers']} inliers)")
closing.finish()

# %% Loops (query, match, inliers, accepted) and the corrected trajectory
loops = closing.loops()
print(f"{len(loops)} loops, {int(loops[:, 3].sum())} accepted by the pose graph")
corrected = closing.corrections()  # ids, poses (N, 4, 4) Sim(3), revision

# %% Evaluate raw and corrected against ground truth (the dict of `sparseloop eval --json`)
out = pathlib.Path(tempfile.mkdtemp(prefix="sparseloop_quickstart_out_"))
scale = np.cbrt(np.linalg.det(corrected["poses"][:, :3, :3]))
rigid = corrected["poses"].copy()
rigid[:, :3, :3] /= scale[:, None, None]  # Sim(3) -> SE(3) for the trajectory file
sparseloop.write_trajectory(str(out / "corrected.txt"), rigid, format="kitti")  # as poses_gt.txt
sparseloop.write_trajectory(str(out / "raw.txt"), raw["poses"], format="kitti")
gt = str(seq / "poses_gt.txt")
for name in ("raw", "corrected"):
    metrics = sparseloop.evaluate_trajectory(gt, str(out / f"{name}.txt"), alignment="sim3")
    print(f"{name:9s} ATE rmse {metrics['ate_rmse_m']:.3f} m")
