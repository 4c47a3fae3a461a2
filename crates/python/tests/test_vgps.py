"""The Python package against the command line and the library's known answers."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import vgps
from vgps._examples import RIG, square_of_landmarks


def write_locate_inputs(tmp: Path, landmarks, bearings, ids, frames=None):
    ids_, lla, _ = landmarks
    lpath = tmp / "landmarks.csv"
    with open(lpath, "w") as f:
        f.write("id,lat,lon,alt\n")
        for i, (lat, lon, alt) in zip(ids_, lla):
            f.write(f"{i},{float(lat)!r},{float(lon)!r},{float(alt)!r}\n")
    opath = tmp / "observations.csv"
    frames = frames if frames is not None else [0] * len(bearings)
    with open(opath, "w") as f:
        f.write("frame,bx,by,bz,landmark\n")
        for fr, b, i in zip(frames, bearings, ids):
            f.write(f"{fr},{float(b[0])!r},{float(b[1])!r},{float(b[2])!r},{i or ''}\n")
    return lpath, opath


def assert_same_reports(ours, theirs):
    """Every field equal, bit for bit, except the RMS residual of an exact problem (a
    rounding-noise value near 1e-10 degrees)."""
    assert len(ours) == len(theirs)
    for a, b in zip(ours, theirs):
        ra, rb = a.pop("rms_residual_deg"), b.pop("rms_residual_deg")
        assert a == b
        assert (ra is None and rb is None) or abs(ra - rb) < 1e-12


def run_cli(cli, *args):
    return subprocess.run([cli, *map(str, args)], capture_output=True, text=True)


# ---- p3p ---------------------------------------------------------------------------------


def random_p3p(rng, n):
    """n random P3P problems with their true poses (world_from_rig)."""
    problems = []
    for _ in range(n):
        angles = rng.uniform(-np.pi, np.pi, 3)
        r = rotation(angles)
        t = rng.uniform(-20, 20, 3)
        points = t + rng.normal(0, 30, (3, 3))
        bearings = (points - t) @ r  # R^T (p - t), row-wise
        problems.append((bearings, points, r, t))
    return problems


def rotation(a):
    cx, sx, cy, sy, cz, sz = np.cos(a[0]), np.sin(a[0]), np.cos(a[1]), np.sin(a[1]), np.cos(a[2]), np.sin(a[2])
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_p3p_finds_the_true_pose_single_and_batched():
    rng = np.random.default_rng(1)
    problems = random_p3p(rng, 200)
    b = np.stack([p[0] for p in problems])
    x = np.stack([p[1] for p in problems])
    batched = vgps.p3p(b, x)
    assert len(batched) == 200
    for (bearings, points, r, t), poses in zip(problems, batched):
        single = vgps.p3p(bearings, points)
        assert single.shape[1:] == (3, 4) and 1 <= single.shape[0] <= 4
        np.testing.assert_array_equal(single, poses)  # same numbers one by one or batched
        err = [max(np.abs(p[:, :3] - r).max(), np.abs(p[:, 3] - t).max()) for p in single]
        assert min(err) < 1e-6


def test_p3p_bad_shapes_and_dtypes_raise_value_error():
    with pytest.raises(ValueError, match="same shape"):
        vgps.p3p(np.zeros((3, 3)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match=r"\(3, 3\) or \(N, 3, 3\)"):
        vgps.p3p(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="bearings"):
        vgps.p3p("not an array", np.zeros((3, 3)))
    # Integer and list input are converted; a degenerate problem has no solution, no NaN.
    assert vgps.p3p([[1, 0, 0]] * 3, [[1, 0, 0]] * 3).shape == (0, 3, 4)


def test_p3p_memory_layouts_and_dtypes_give_the_same_poses():
    """The per-call fast path (C-contiguous float64 (3, 3)) and the general path (any
    layout, any dtype NumPy converts) agree: Fortran order, strided views, float32."""
    rng = np.random.default_rng(3)
    (bearings, points, _, _), = random_p3p(rng, 1)
    expected = vgps.p3p(bearings, points)
    assert expected.shape[0] >= 1 and expected.flags["C_CONTIGUOUS"]
    wide_b, wide_p = np.zeros((3, 6)), np.zeros((3, 6))
    wide_b[:, ::2], wide_p[:, ::2] = bearings, points
    for b, p in [
        (np.asfortranarray(bearings), np.asfortranarray(points)),
        (wide_b[:, ::2], wide_p[:, ::2]),  # strided views
        (bearings.tolist(), points),
    ]:
        np.testing.assert_array_equal(vgps.p3p(b, p), expected)
    single = vgps.p3p(bearings.astype(np.float32), points.astype(np.float32))
    assert single.dtype == np.float64 and single.shape[1:] == (3, 4)
    with pytest.raises(ValueError, match="points"):
        vgps.p3p(bearings, "not an array")


def test_p3p_agrees_with_poselib():
    poselib = pytest.importorskip("poselib")
    rng = np.random.default_rng(7)
    same_set = 0
    problems = random_p3p(rng, 300)
    for bearings, points, r, t in problems:
        ours = vgps.p3p(bearings, points)
        unit = bearings / np.linalg.norm(bearings, axis=1, keepdims=True)
        theirs = poselib.p3p(list(unit), list(points))
        # PoseLib's pose is camera_from_world: x = R X + t; ours world_from_rig [R | t].
        theirs_wfr = [(p.R.T, -p.R.T @ p.t) for p in theirs]
        for rr, tt in [(r, t)]:
            assert min(np.abs(p[:, 3] - tt).max() for p in ours) < 1e-6
            assert min(np.abs(q[1] - tt).max() for q in theirs_wfr) < 1e-6
        matched = all(
            min(max(np.abs(p[:, :3] - q[0]).max(), np.abs(p[:, 3] - q[1]).max()) for p in ours) < 1e-5
            for q in theirs_wfr
        )
        same_set += matched and len(theirs_wfr) == len(ours)
    # Both solvers give the same solution sets on nearly every frame (they differ only in
    # near-degenerate roots one of them keeps).
    assert same_set >= 0.97 * len(problems), same_set


# ---- locate ------------------------------------------------------------------------------


def test_locate_known_ids_equals_the_cli(tmp_path, vgps_cli):
    landmarks, bearings, ids = square_of_landmarks(heading_deg=30.0)
    ours = vgps.locate(landmarks, bearings, ids=ids)
    assert ours[0]["status"] == "ok"
    assert abs(ours[0]["lat"] - RIG[0]) < 1e-9 and abs(ours[0]["lon"] - RIG[1]) < 1e-9
    assert abs(ours[0]["heading_deg"] - 30.0) < 1e-6
    lpath, opath = write_locate_inputs(tmp_path, landmarks, bearings, ids)
    cli = run_cli(vgps_cli, "locate", "--landmarks", lpath, "--observations", opath)
    assert cli.returncode == 0, cli.stderr
    theirs = [json.loads(line) for line in cli.stdout.splitlines()]
    assert_same_reports(ours, theirs)


def test_locate_with_the_matcher_and_a_prior_equals_the_cli(tmp_path, vgps_cli):
    landmarks, bearings, ids = square_of_landmarks(heading_deg=-50.0)
    prior = (RIG[0] + 0.0001, RIG[1], RIG[2], 40.0)
    ours = vgps.locate(landmarks, bearings, prior=prior, up_tolerance_deg=2.0)
    assert ours[0]["status"] == "ok", ours[0]["message"]
    assert ours[0]["landmarks"] == ids
    lpath, opath = write_locate_inputs(tmp_path, landmarks, bearings, [None] * len(ids))
    cli = run_cli(vgps_cli, "locate", "--landmarks", lpath, "--observations", opath,
                  "--prior", ",".join(map(repr, prior)), "--up-tolerance-deg", "2")
    assert cli.returncode == 0, cli.stderr
    assert_same_reports(ours, [json.loads(line) for line in cli.stdout.splitlines()])


def test_locate_errors_carry_the_cli_message(tmp_path, vgps_cli):
    landmarks, bearings, ids = square_of_landmarks()
    bad = ids[:-1] + ["nope"]
    lpath, opath = write_locate_inputs(tmp_path, landmarks, bearings, bad)
    with pytest.raises(vgps.VgpsError) as e:
        vgps.locate(str(lpath), bearings, ids=bad)
    cli = run_cli(vgps_cli, "locate", "--landmarks", lpath, "--observations", opath)
    assert cli.returncode == 2
    assert "unknown landmark id `nope`" in str(e.value)
    # Same message but for the observations' origin (a file for the CLI, an array here).
    assert str(e.value).split(": ", 2)[-1] in cli.stderr
    with pytest.raises(ValueError, match=r"bearings: expected an array of shape \(N, 3\)"):
        vgps.locate(landmarks, bearings[:, :2], ids=ids)
    with pytest.raises(ValueError, match="exactly one of bearings"):
        vgps.locate(landmarks)
    with pytest.raises(vgps.VgpsError, match="no such file|No such file|cannot|not"):
        vgps.locate(str(tmp_path / "missing.csv"), bearings, ids=ids)


# ---- triangulation -----------------------------------------------------------------------


def test_triangulate_known_answer_and_errors():
    origins = np.array([[0.0, 0, 0], [10, 0, 0], [5, -5, 0]])
    target = np.array([5.0, 5.0, 2.0])
    r = vgps.triangulate(origins, target - origins, sigma_rad=1e-3)
    np.testing.assert_allclose(r["point"], target, atol=1e-9)
    assert r["covariance"].shape == (3, 3) and np.all(np.linalg.eigvalsh(r["covariance"]) > 0)
    assert r["n_obs"] == 3
    with pytest.raises(vgps.VgpsError):
        vgps.triangulate(origins[:2], np.array([[1.0, 0, 0], [1.0, 0, 0]]))
    with pytest.raises(ValueError, match="origins has 3 rows and directions 2"):
        vgps.triangulate(origins, np.ones((2, 3)))


# ---- calibration -------------------------------------------------------------------------


def test_calibration_pixel_bearing_round_trip_batched(root):
    cal = vgps.Calibration.load(root / "calibration" / "equirectangular_2048x1024.json")
    assert len(cal) == 1 and cal.image_sizes == [(2048, 1024)]
    rng = np.random.default_rng(3)
    pixels = np.column_stack([rng.uniform(0, 2047, 10000), rng.uniform(1, 1022, 10000)])
    bearings = cal.pixel_to_bearing(pixels)
    assert bearings.shape == (10000, 3)
    np.testing.assert_allclose(np.linalg.norm(bearings, axis=1), 1.0, atol=1e-12)
    back, visible, camera = cal.bearing_to_pixel(bearings)
    assert visible.all() and (camera == 0).all()
    np.testing.assert_allclose(back, pixels, atol=1e-6)
    with pytest.raises(vgps.VgpsError, match="pixels row 1"):
        cal.pixel_to_bearing(np.array([[10.0, 10.0], [1e6, 10.0]]))
    with pytest.raises(ValueError, match=r"pixels: expected an array of shape \(N, 2\)"):
        cal.pixel_to_bearing(np.zeros((4, 3)))
    with pytest.raises(vgps.VgpsError, match="missing.json"):
        vgps.Calibration.load(root / "missing.json")


# ---- simulate, replay, Localizer ---------------------------------------------------------


@pytest.fixture(scope="module")
def small_drive(tmp_path_factory):
    d = tmp_path_factory.mktemp("sim") / "drive"
    vgps.simulate(d, preset="short", length_m=80, seed=5)
    return d


def test_replay_equals_the_cli(small_drive, tmp_path, vgps_cli):
    report = vgps.replay(small_drive, tmp_path / "py")
    assert report["frames"] > 0
    cli = run_cli(vgps_cli, "replay", small_drive, "--out", tmp_path / "cli", "--quiet")
    assert cli.returncode == 0, cli.stderr
    for name in ["fixes.csv", "report.json"]:
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name


def test_replay_of_a_missing_or_corrupt_drive_raises(tmp_path, vgps_cli):
    with pytest.raises(vgps.VgpsError) as e:
        vgps.replay(tmp_path / "nothing", tmp_path / "out")
    cli = run_cli(vgps_cli, "replay", tmp_path / "nothing", "--out", tmp_path / "out2", "--quiet")
    assert cli.returncode != 0 and str(e.value) in cli.stderr
    (tmp_path / "corrupt").mkdir()
    (tmp_path / "corrupt" / "drive.json").write_text("{ not json")
    with pytest.raises(vgps.VgpsError, match="drive.json"):
        vgps.replay(tmp_path / "corrupt", tmp_path / "out")


def test_localizer_frame_by_frame_on_a_simulated_drive(small_drive):
    drive = json.loads((small_drive / "drive.json").read_text())
    cal = vgps.Calibration.load(small_drive / drive["calibration"])
    loc = vgps.Localizer(cal, small_drive / drive["landmarks"])
    read = lambda name: np.genfromtxt(small_drive / name, delimiter=",", names=True, dtype=None, encoding="utf-8")
    det, frames, truth = read(drive["detections"]), read(drive["frames"]), read(drive["truth"])
    ok = 0
    for k, fr in enumerate(frames[:30]):
        rows = det[det["frame"] == fr["frame"]]
        pixels = np.column_stack([rows["u"], rows["v"]])
        t = truth[truth["frame"] == fr["frame"]][0]
        # The first frame is found around a GPS-like prior (the truth), the others tracked.
        g = (float(t["lat"]), float(t["lon"]), float(t["alt"])) if k == 0 else None
        fix = loc.process(float(fr["time_s"]), pixels=pixels, camera=rows["camera"].astype(int), gnss=g,
                          classes=[str(c) or None for c in rows["class"]])
        if fix["status"] == "ok":
            ok += 1
            assert fix["covariance"].shape == (6, 6)
            assert fix["enu_from_rig_wxyz"][0] >= 0
            east = (fix["lat_lon_alt"][1] - t["lon"]) * 111320 * np.cos(np.radians(t["lat"]))
            north = (fix["lat_lon_alt"][0] - t["lat"]) * 110540
            assert np.hypot(east, north) < 2.0
    assert ok >= 25, ok
    with pytest.raises(ValueError, match="pixels"):
        loc.process(0.0, pixels=np.zeros((3, 3)))


def test_localizer_refuses_a_negative_turn_rate_change(small_drive):
    drive = json.loads((small_drive / "drive.json").read_text())
    cal = vgps.Calibration.load(small_drive / drive["calibration"])
    landmarks = small_drive / drive["landmarks"]
    vgps.Localizer(cal, landmarks, max_turn_rate_change_deg_s=0.0)  # off: allowed
    with pytest.raises(vgps.VgpsError, match="max_turn_rate_change_rad_s"):
        vgps.Localizer(cal, landmarks, max_turn_rate_change_deg_s=-1.0)


def test_localizer_backward_tracks_a_drive_in_reverse(small_drive):
    drive = json.loads((small_drive / "drive.json").read_text())
    cal = vgps.Calibration.load(small_drive / drive["calibration"])
    loc = vgps.Localizer(cal, small_drive / drive["landmarks"], cold_start=False)
    read = lambda name: np.genfromtxt(small_drive / name, delimiter=",", names=True, dtype=None, encoding="utf-8")
    det, frames, truth = read(drive["detections"]), read(drive["frames"]), read(drive["truth"])
    ok = 0
    last = frames[:30][::-1]
    for k, fr in enumerate(last):
        rows = det[det["frame"] == fr["frame"]]
        t = truth[truth["frame"] == fr["frame"]][0]
        # Only the last frame has a prior; the backward pass tracks from it to the first.
        g = (float(t["lat"]), float(t["lon"]), float(t["alt"])) if k == 0 else None
        fix = loc.process(float(fr["time_s"]), pixels=np.column_stack([rows["u"], rows["v"]]),
                          camera=rows["camera"].astype(int), gnss=g,
                          classes=[str(c) or None for c in rows["class"]], backward=True)
        assert fix["time_s"] == float(fr["time_s"])
        if fix["status"] == "ok":
            ok += 1
            east = (fix["lat_lon_alt"][1] - t["lon"]) * 111320 * np.cos(np.radians(t["lat"]))
            north = (fix["lat_lon_alt"][0] - t["lat"]) * 110540
            assert np.hypot(east, north) < 2.0
    assert ok >= 25, ok


# ---- docstrings --------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["vgps", "p3p", "triangulate", "Calibration", "locate", "simulate", "replay"])
def test_docstring_examples_run(name, root, monkeypatch):
    import doctest

    obj = vgps if name == "vgps" else getattr(vgps, name)
    assert obj.__doc__ and ">>>" in obj.__doc__, f"{name} has no example"
    monkeypatch.chdir(root)  # examples name files of the repository by relative path
    test = doctest.DocTestParser().get_doctest(obj.__doc__, {}, name, None, 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    runner.run(test)
    assert runner.failures == 0 and runner.tries > 0


def test_vgps_error_pickles_as_itself():
    """Errors cross process boundaries (multiprocessing, Ray) as vgps.VgpsError."""
    import pickle

    err = pickle.loads(pickle.dumps(vgps.VgpsError("drive.json: bad")))
    assert type(err) is vgps.VgpsError and str(err) == "drive.json: bad"
