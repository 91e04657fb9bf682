"""The Python module against the CLI and against known answers (python/sparseloop_module.cc)."""
import csv
import json
import subprocess

import numpy as np
import pytest

import sparseloop


def read_frames(seq):
    """The frames as `sparseloop run --dataset kitti:SEQ --poses SEQ/poses_raw.txt` builds them."""
    p0 = [float(v) for v in (seq / "calib.txt").read_text().splitlines()[0].split()[1:]]
    intrinsics = (p0[0], p0[5], p0[2], p0[6])
    times = [float(t) for t in (seq / "times.txt").read_text().split()]
    raw = sparseloop.read_trajectory(str(seq / "poses_raw.txt"))
    assert len(raw["poses"]) == len(times)
    for i, t in enumerate(times):
        pixels, depths = sparseloop.read_mapped_pixels(str(seq / "mapped" / f"{i:06d}.txt"))
        yield dict(id=i, timestamp=t, image=sparseloop.read_image(str(seq / "image_0" / f"{i:06d}.png")),
                   intrinsics=intrinsics, pose=raw["poses"][i], mapped_pixels=pixels,
                   mapped_depths=depths)


def test_same_loops_and_trajectory_as_cli_run(sequence, cli, tmp_path):
    out = tmp_path / "run"
    subprocess.run([cli, "run", "--dataset", f"kitti:{sequence}", "--poses",
                    str(sequence / "poses_raw.txt"), "--out", str(out)],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(out / "loops.csv") as f:
        rows = list(csv.DictReader(f))
    cli_loops = [(int(r["query"]), int(r["match"])) for r in rows]
    cli_accepted = [(int(r["query"]), int(r["match"])) for r in rows if r["accepted"] == "1"]
    assert len(cli_loops) >= 10  # the second lap closes loops

    # solve_while_running=False: one solve in finish() over every loop, as `run` does.
    closing = sparseloop.LoopClosing(solve_while_running=False)
    statuses = [closing.add_keyframe(**frame)["status"] for frame in read_frames(sequence)]
    closing.finish()
    loops = closing.loops()
    assert loops.dtype == np.int64 and loops.shape == (len(cli_loops), 4)
    assert [tuple(l[:2]) for l in loops] == cli_loops
    assert [tuple(l[:2]) for l in loops if l[3] == 1] == cli_accepted
    assert statuses.count("detected") == len(cli_loops)

    corrected = closing.corrections()
    ref = sparseloop.read_trajectory(str(out / "trajectory.txt"))
    np.testing.assert_array_equal(corrected["ids"], np.arange(60))
    assert corrected["num_solved"] == 60 and closing.num_solves == 1
    # Same detector, graph and deterministic solve (tests/runtime/loop_closing_test.cc: 1e-9);
    # trajectory.txt prints 15-16 significant digits of positions up to ~100 m, so 1e-6 m covers
    # the text round-off. A single different loop moves poses by metres.
    position_gap = np.abs(corrected["poses"][:, :3, 3] - ref["poses"][:, :3, 3]).max()
    assert position_gap < 1e-6
    # Corrected poses are Sim(3): compare rotations with the scale divided out.
    scale = np.cbrt(np.linalg.det(corrected["poses"][:, :3, :3]))
    rotations = corrected["poses"][:, :3, :3] / scale[:, None, None]
    assert np.abs(rotations - ref["poses"][:, :3, :3]).max() < 1e-6
    # The drift was corrected: the corrected trajectory differs from the raw one by metres.
    raw = sparseloop.read_trajectory(str(sequence / "poses_raw.txt"))
    assert np.abs(corrected["poses"][:, :3, 3] - raw["poses"][:, :3, 3]).max() > 1.0


def test_callback_runs_on_each_solve_with_the_gil(sequence):
    seen = []
    closing = sparseloop.LoopClosing(config={"optimizer": {"rejection": "pcm"}},
                                     on_correction=lambda c: seen.append(int(c["revision"])))
    for frame in read_frames(sequence):
        closing.add_keyframe(**frame)
    closing.finish()
    # One callback per completed solve; a solve that a newer loop interrupted (a busy machine) is
    # re-run at once without a callback.
    assert seen and seen == list(range(1, len(seen) + 1))
    assert closing.num_solves == len(seen) + closing.num_interrupted_solves
    assert closing.corrected_pose(59).shape == (4, 4)
    assert closing.corrected_pose(1000) is None


def blank(i, **kw):
    args = dict(id=i, timestamp=0.1 * i, image=np.full((120, 160), 128, np.uint8),
                intrinsics=(150.0, 150.0, 79.5, 59.5), pose=np.eye(4))
    args.update(kw)
    return args


def test_bad_input_raises_with_the_library_message():
    closing = sparseloop.LoopClosing()
    with pytest.raises(ValueError, match="uint8"):
        closing.add_keyframe(**blank(0, image=np.zeros((120, 160), np.float32)))
    with pytest.raises(ValueError, match=r"4x4 or 3x4"):
        closing.add_keyframe(**blank(0, pose=np.eye(3)))
    with pytest.raises(ValueError, match="scaled rotation"):
        closing.add_keyframe(**blank(0, pose=np.diag([1.0, 2.0, 1.0, 1.0])))
    event = closing.add_keyframe(**blank(1, pose=(np.eye(3), np.zeros(3))))
    assert event["status"] == "no_features" and event["in_graph"]
    # Nested lists are matrices, as numpy arrays are: 4 rows, or 3 rows of [R | t].
    rows = [[1.0, 0.0, 0.0, 0.5], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]
    closing.add_keyframe(**blank(2, pose=rows + [[0.0, 0.0, 0.0, 1.0]]))
    closing.add_keyframe(**blank(3, pose=rows))
    assert np.allclose(closing.corrected_pose(3)[:3, 3], [0.5, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"pose: a pose must be a 4x4 or 3x4 matrix"):
        closing.add_keyframe(**blank(4, pose=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
    with pytest.raises(ValueError, match=r"pose: expected numbers .* got 'abc'"):
        closing.add_keyframe(**blank(4, pose="abc"))
    with pytest.raises(ValueError, match=r"R of shape \(3, 3\) and t of 3 values"):
        closing.add_keyframe(**blank(4, pose=(np.eye(3), [0.0, 0.0])))
    with pytest.raises(ValueError, match=r"shape \(6, 6\)"):
        closing.add_keyframe(**blank(4, pose=np.eye(4)), odometry_covariance=np.eye(3))
    with pytest.raises(ValueError, match="odometry_covariance: odometry covariance must be positive"):
        closing.add_keyframe(**blank(4, pose=np.eye(4)), odometry_covariance=-np.eye(6))
    closing.add_keyframe(**blank(4, pose=np.eye(4)), odometry_covariance=np.eye(6) * 1e-4)
    # Ids must increase: the C++ check's message, unchanged.
    with pytest.raises(ValueError, match=r"keyframe id 1 must be greater than the previous"):
        closing.add_keyframe(**blank(1))
    closing.finish()
    with pytest.raises(ValueError):
        closing.add_keyframe(**blank(5))


def test_arguments_are_validated_as_the_cli_reads_files():
    """Each bad argument is a ValueError naming it (README): never a pybind11 cast error."""
    closing = sparseloop.LoopClosing(optimize=False)
    # A transposed pose (translation in the bottom row) put every position at the origin.
    transposed = np.eye(4)
    transposed[3, :3] = (1.0, 2.0, 3.0)
    with pytest.raises(ValueError, match=r"pose: expected a 4x4 pose with last row \[0, 0, 0, 1\]"):
        closing.add_keyframe(**blank(0, pose=transposed))
    # Rotations rounded to 6 digits (the castle GT) or float32: within the CLI reader's 1e-3.
    c, s_ = np.cos(0.3), np.sin(0.3)
    rounded = np.eye(4)
    rounded[:3, :3] = np.round([[c, -s_, 0], [s_, c, 0], [0, 0, 1]], 6)
    rounded[0, 3] = 1.0
    closing.add_keyframe(**blank(0, pose=rounded))
    closing.add_keyframe(**blank(1, pose=rounded.astype(np.float32)))
    with pytest.raises(ValueError, match=r"pose: .*not a scaled rotation"):
        skewed = np.eye(4)
        skewed[0, 1] = 0.01
        closing.add_keyframe(**blank(2, pose=skewed))
    with pytest.raises(ValueError, match=r"pose: translation beyond"):
        far = np.eye(4)
        far[0, 3] = 1e200
        closing.add_keyframe(**blank(2, pose=far))
    # Depths that are NaN, negative or zero cost the loop silently; inf was the only one refused.
    pixels = np.array([[10.0, 10.0], [20.0, 20.0]], np.float32)
    for bad in (np.nan, -1.0, 0.0, np.inf):
        with pytest.raises(ValueError, match=r"mapped_depths\[1\]: expected a positive, finite depth"):
            closing.add_keyframe(**blank(2), mapped_pixels=pixels,
                                 mapped_depths=np.array([1.0, bad], np.float32))
    # Intrinsics: a 3x3 K or None name the argument (they raised pybind11's cast error).
    k = np.array([[150.0, 0, 79.5], [0, 150.0, 59.5], [0, 0, 1]])
    with pytest.raises(ValueError, match=r"intrinsics: expected \(fx, fy, cx, cy\).*K\[0, 0\]"):
        closing.add_keyframe(**blank(2, intrinsics=k))
    with pytest.raises(ValueError, match=r"intrinsics: expected numbers"):
        closing.add_keyframe(**blank(2, intrinsics=None))
    with pytest.raises(ValueError, match=r"intrinsics: fx must be at most"):
        closing.add_keyframe(**blank(2, intrinsics=(1e308, 1e308, 79.5, 59.5)))
    closing.add_keyframe(**blank(2))
    # A NaN in a config dict names the key (it raised RuntimeError with "line 1, column 44").
    with pytest.raises(ValueError, match=r'config: expected a finite number for "detector.min_path_ratio"'):
        sparseloop.LoopClosing(config={"detector": {"min_path_ratio": float("nan")}})


def test_config_keys_are_the_cli_registry(cli):
    cli_dump = json.loads(subprocess.run([cli, "config", "--dump", "run"], check=True,
                                         capture_output=True, text=True).stdout)
    assert sparseloop.default_config() == cli_dump
    with pytest.raises(sparseloop.FileError, match="detector.features.max_feature"):
        sparseloop.LoopClosing(config={"detector": {"features": {"max_feature": 15}}})
    # An invalid value: the options' Check() message, inside the config error naming the source.
    with pytest.raises(sparseloop.FileError, match=r"max_features \(K\) must be in \[5, 10000\]"):
        sparseloop.LoopClosing(config={"detector": {"features": {"max_features": -1}}})
    sparseloop.LoopClosing(config={"detector": {"features": {"max_features": 15}}}, optimize=False)


def rotation_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def test_trajectory_round_trip_and_file_errors(tmp_path):
    poses = np.tile(np.eye(4), (5, 1, 1))
    for i in range(5):
        poses[i, :3, :3] = rotation_z(0.3 * i)
        poses[i, :3, 3] = [i, 2.0 * i, -0.5 * i]
    stamps = 10.0 + 0.25 * np.arange(5)
    for fmt in ("tum", "kitti", "euroc"):
        path = tmp_path / f"traj.{fmt}"
        sparseloop.write_trajectory(str(path), poses, stamps, format=fmt)
        back = sparseloop.read_trajectory(str(path), fmt)
        np.testing.assert_allclose(back["poses"], poses, atol=1e-9)
        if fmt != "kitti":
            np.testing.assert_allclose(back["timestamps"], stamps, atol=1e-6)
    bad = tmp_path / "bad.txt"
    bad.write_text("0 1 2 3 0 0 0 1\n1 1 2\n")
    with pytest.raises(sparseloop.FileError, match=r"bad.txt:2: expected"):
        sparseloop.read_trajectory(str(bad), "tum")
    with pytest.raises(sparseloop.Error):
        sparseloop.read_trajectory(str(tmp_path / "missing.txt"), "tum")
    with pytest.raises(ValueError, match="one value per pose"):
        sparseloop.write_trajectory(str(tmp_path / "x.txt"), poses, stamps[:3])


def test_eval_dict_has_known_values(tmp_path):
    """est = gt with +-0.1 m in z (alternating); without alignment every ATE error is 0.1 m."""
    n = 20
    gt = np.tile(np.eye(4), (n, 1, 1))
    gt[:, 0, 3] = np.arange(n)  # a straight line along x, 1 m apart
    gt[:, 1, 3] = np.where(np.arange(n) % 2 == 0, 0.0, 1.0)  # zigzag keeps the geometry 2-D
    est = gt.copy()
    est[:, 2, 3] = np.where(np.arange(n) % 2 == 0, 0.1, -0.1)  # +-0.1 m in z: mean zero
    stamps = np.arange(n, dtype=float)
    sparseloop.write_trajectory(str(tmp_path / "gt.txt"), gt, stamps)
    sparseloop.write_trajectory(str(tmp_path / "est.txt"), est, stamps)
    same = sparseloop.evaluate_trajectory(str(tmp_path / "gt.txt"), str(tmp_path / "gt.txt"))
    assert same["ate_rmse_m"] == pytest.approx(0.0, abs=1e-9)
    ev = sparseloop.evaluate_trajectory(str(tmp_path / "gt.txt"), str(tmp_path / "est.txt"),
                                        alignment="none")
    assert ev["ate_rmse_m"] == pytest.approx(0.1, abs=1e-9)  # every position is 0.1 m off
    assert ev["ate"]["max"] == pytest.approx(0.1, abs=1e-9)
    # Pose by pose, as `sparseloop eval --json` writes it: every pair and the aligned estimate.
    assert ev["associated"]["gt_index"] == list(range(n))
    assert ev["associated"]["ate_m"] == pytest.approx([0.1] * n, abs=1e-9)
    assert np.asarray(ev["aligned_positions"]) == pytest.approx(est[:, :3, 3], abs=1e-9)
    with pytest.raises(ValueError):
        sparseloop.evaluate_trajectory(str(tmp_path / "gt.txt"), str(tmp_path / "gt.txt"),
                                       alignment="bogus")


def test_paths_may_be_pathlib_paths(tmp_path):
    """Every path argument takes os.PathLike as open() does (a pathlib.Path was a pybind11
    TypeError)."""
    path = tmp_path / "t.txt"
    sparseloop.write_trajectory(path, np.stack([np.eye(4)] * 3), [0.0, 1.0, 2.0])
    read = sparseloop.read_trajectory(path)
    assert read["poses"].shape == (3, 4, 4)
    assert sparseloop.evaluate_trajectory(path, path)["ate"]["rmse"] == pytest.approx(0.0)
    with pytest.raises(sparseloop.FileError):
        sparseloop.read_mapped_pixels(tmp_path / "missing.txt")


def test_presets_configure_the_closer_and_an_unknown_one_is_named():
    assert sparseloop.presets() == ["dense", "sparse"]
    sparse = sparseloop.default_config("detect", preset="sparse")
    assert sparse["detector"]["features"]["max_features"] == 20
    assert sparse["detector"]["asymmetric_matching"] is True
    # config goes on top of the preset
    closing = sparseloop.LoopClosing(preset="sparse", config={"detector": {"check_every": 2}})
    closing.add_keyframe(**blank(0))
    closing.finish()
    with pytest.raises(ValueError, match=r"preset: expected a preset name \(dense \| sparse\), got 'tiny'"):
        sparseloop.LoopClosing(preset="tiny")
    with pytest.raises(ValueError, match=r"preset: expected a preset name \(dense \| sparse\) or None, got 3"):
        sparseloop.LoopClosing(preset=3)
    sparseloop.LoopClosing(preset=None)  # the defaults
    # The CLI's scope names; others refused (they returned an empty dump).
    assert sparseloop.default_config("detect").keys() == {"detector", "doc"}
    assert "optimizer" in sparseloop.default_config("run")
    with pytest.raises(ValueError, match=r"scope: expected 'run' \(every key\) or 'detect', got 'bogus'"):
        sparseloop.default_config("bogus")
    with pytest.raises(ValueError, match=r"on_correction: expected a callable or None, got 5"):
        sparseloop.LoopClosing(on_correction=5)


def test_numpy_scalars_in_a_config_dict_are_their_values(tmp_path):
    """numpy scalars (what arithmetic on arrays gives) are read as the Python numbers they hold;
    they were a ValueError quoting json's traceback. A path-like config is the file."""
    config = {"detector": {"min_path_ratio": np.float64(0.3), "check_every": np.int64(2),
                           "features": {"max_features": np.int32(15)}},
              "use_mapped_pixels": np.bool_(False)}
    closing = sparseloop.LoopClosing(config=config, optimize=False)
    closing.add_keyframe(**blank(0))
    closing.finish()
    with pytest.raises(ValueError, match=r'config: expected a finite number for "detector.min_path_ratio"'):
        sparseloop.LoopClosing(config={"detector": {"min_path_ratio": np.float32("nan")}})
    # What JSON cannot hold names its key, and never shows a traceback.
    with pytest.raises(ValueError, match=r'config: .*"detector.check_every".*object') as error:
        sparseloop.LoopClosing(config={"detector": {"check_every": object()}})
    assert "Traceback" not in str(error.value) and "json" not in str(error.value)
    (tmp_path / "c.json").write_text('{"detector": {"check_every": 0}}')
    with pytest.raises(sparseloop.FileError, match=r"c.json"):
        sparseloop.LoopClosing(config=tmp_path / "c.json")


def test_mapped_pixels_must_be_finite():
    """A NaN or infinite pixel is refused naming the argument and the row, as the CLI's reader
    refuses a non-finite number in a mapped-pixels file (a NaN pixel was accepted)."""
    closing = sparseloop.LoopClosing(optimize=False)
    for bad in ([np.nan, 10.0], [10.0, np.inf]):
        pixels = np.array([[10.0, 10.0], bad], np.float32)
        with pytest.raises(ValueError, match=r"mapped_pixels\[1\]: expected finite pixel coordinates"):
            closing.add_keyframe(**blank(0), mapped_pixels=pixels)
    with pytest.raises(ValueError, match=r"mapped_pixels: expected shape \(N, 2\)"):
        closing.add_keyframe(**blank(0), mapped_pixels=np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"mapped_pixels: expected numbers"):
        closing.add_keyframe(**blank(0), mapped_pixels="abc")
    closing.add_keyframe(**blank(0), mapped_pixels=np.array([[10.0, 10.0]]))


def test_written_times_read_back_distinct(tmp_path):
    """Times closer than a format's resolution: TUM keeps them distinct, EuRoC (integer
    nanoseconds) refuses them naming the frame; both were written equal and refused on reading."""
    poses = np.stack([np.eye(4)] * 3)
    stamps = [1.0, 1.0 + 1e-10, 1.0 + 2e-10]
    sparseloop.write_trajectory(tmp_path / "t.txt", poses, stamps, format="tum")
    back = sparseloop.read_trajectory(tmp_path / "t.txt")
    assert list(back["timestamps"]) == stamps
    with pytest.raises(ValueError, match=r"frame 1"):
        sparseloop.write_trajectory(tmp_path / "e.csv", poses, stamps, format="euroc")
    with pytest.raises(ValueError, match=r"frame 0"):
        sparseloop.write_trajectory(tmp_path / "e.csv", poses, [1e10, 1e10 + 1, 1e10 + 2],
                                    format="euroc")
    assert not (tmp_path / "e.csv").exists()


def test_a_tiny_image_is_refused_with_the_minimum_size():
    """A 1x1 image came back as OpenCV's raw resize assertion: it is a ValueError giving the
    size and the minimum the feature extraction takes."""
    closing = sparseloop.LoopClosing(optimize=False)
    with pytest.raises(ValueError, match=r"image of 1x1 pixels is too small: expected at least 32x32"):
        closing.add_keyframe(id=1, timestamp=0.0, image=np.zeros((1, 1), np.uint8),
                             intrinsics=(1, 1, 0.5, 0.5), pose=np.eye(4))
    closing.add_keyframe(id=1, timestamp=0.0, image=np.zeros((32, 32), np.uint8),
                         intrinsics=(1, 1, 0.5, 0.5), pose=np.eye(4))


def test_an_odometry_covariance_too_small_to_invert_is_refused():
    """Variances of 1e-30 were taken and the background solve aborted the interpreter at
    finish(): the argument is refused, naming it and the floor."""
    closing = sparseloop.LoopClosing()
    closing.add_keyframe(**blank(0, pose=np.eye(4)))
    for tiny in (1e-30, 1e-308):
        with pytest.raises(ValueError, match=r"odometry_covariance: .*eigenvalues of at least 1e-18"):
            closing.add_keyframe(**blank(1, pose=np.eye(4)), odometry_covariance=np.eye(6) * tiny)
    closing.add_keyframe(**blank(1, pose=np.eye(4)), odometry_covariance=np.eye(6) * 1e-4)
    closing.finish()


def test_a_deeply_nested_config_file_is_refused_before_parsing(tmp_path):
    """200000 levels of {"a": ...} took the parser > 30 s: more than 64 is a FileError naming the
    file, the line and the column."""
    deep = tmp_path / "deep.json"
    deep.write_text('{"x": ' + '{"a":' * 200000 + "1" + "}" * 200001)
    with pytest.raises(sparseloop.FileError, match=r"deep\.json:1: expected JSON nested at most 64 deep"):
        sparseloop.LoopClosing(config=str(deep), optimize=False)


def test_read_mapped_pixels_refuses_a_depth_beyond_float(tmp_path):
    """1e39 (or 1e308) read as inf: a FileError naming the file and the line."""
    for big in ("1e39", "1e308"):
        path = tmp_path / "000000.txt"
        path.write_text(f"1 2 3\n4 5 {big}\n")
        with pytest.raises(sparseloop.FileError, match=r"000000\.txt:2: expected a depth within float range"):
            sparseloop.read_mapped_pixels(str(path))
