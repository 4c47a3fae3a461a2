"""vgps.fleet.replay_many on a local Ray instance: three small simulated drives, one broken,
one missing; a worker killed mid-task; the summary against each drive's report.json."""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import vgps

# Short routes: each replay takes well under a second (the whole module about 10 s, most of
# it starting Ray).
LENGTH_M = 80


@pytest.fixture(scope="module")
def ray_local(tmp_path_factory):
    ray = pytest.importorskip(
        "ray", reason="Ray is not installed (pip install 'vgps[fleet]'); fleet tests skipped"
    )
    crash_dir = tmp_path_factory.mktemp("crash")
    # The workers inherit the driver's environment: the test hook that kills a worker once.
    os.environ["_VGPS_FLEET_TEST_CRASH_DIR"] = str(crash_dir)
    # Tasks at normal priority (Ray's default is nice 15: slow on a loaded CI machine).
    set_niceness = "RAY_worker_niceness" not in os.environ
    os.environ.setdefault("RAY_worker_niceness", "0")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             configure_logging=False)
    yield crash_dir
    ray.shutdown()
    os.environ.pop("_VGPS_FLEET_TEST_CRASH_DIR", None)
    if set_niceness:
        os.environ.pop("RAY_worker_niceness", None)


@pytest.fixture(scope="module")
def drives(tmp_path_factory):
    root = tmp_path_factory.mktemp("drives")
    good_a, good_b, broken = root / "good_a", root / "good_b", root / "broken"
    vgps.simulate(good_a, preset="short", length_m=LENGTH_M, seed=1)
    vgps.simulate(good_b, preset="short", length_m=LENGTH_M, seed=2)
    vgps.simulate(broken, preset="short", length_m=LENGTH_M, seed=3)
    (broken / "drive.json").write_text('{"version": 1, "calibration": ')  # cut short
    return good_a, good_b, broken


def figures(report):
    """The summary's figures, written out from report.json's own keys."""
    h = lambda section, stat: (report[section] or {}).get("horizontal_m", {}).get(stat)
    return {
        "frames": report["frames"],
        "visual_fixes": report["visual_fixes"],
        "fix_rate": report["visual_fix_rate"],
        "cep50_vs_truth_m": h("visual_vs_truth", "cep50"),
        "cep95_vs_truth_m": h("visual_vs_truth", "cep95"),
        "cep50_vs_gnss_m": h("visual_vs_gnss", "cep50"),
        "cep95_vs_gnss_m": h("visual_vs_gnss", "cep95"),
        "gnss_cep50_vs_truth_m": h("gnss_vs_truth", "cep50"),
        "gnss_cep95_vs_truth_m": h("gnss_vs_truth", "cep95"),
    }


def test_import_vgps_does_not_import_ray():
    code = ("import sys, vgps; assert 'ray' not in sys.modules; import vgps.fleet; "
            "assert 'ray' not in sys.modules and vgps.fleet.replay_many; print('ok')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "ok", out.stderr


def test_replay_many_broken_and_missing_drives_fail_alone(ray_local, drives, tmp_path, capsys,
                                                          monkeypatch):
    from vgps.fleet import SUMMARY_FIELDS, replay_many

    good_a, good_b, broken = drives
    missing = good_a.parent / "no_such_drive"
    out = tmp_path / "fleet"
    monkeypatch.setitem(sys.modules, "tqdm", None)  # the plain progress line, even with tqdm
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)
    rows = replay_many([good_a, broken, missing, good_b], out)
    assert "vgps fleet: 4/4 drives done, 2 failed" in capsys.readouterr().err

    assert [r["drive"] for r in rows] == ["good_a", "broken", "no_such_drive", "good_b"]
    assert [r["status"] for r in rows] == ["ok", "failed", "failed", "ok"]
    assert str(broken) in rows[1]["error"] and "drive.json" in rows[1]["error"]
    assert str(missing) in rows[2]["error"]
    for r in rows[1:3]:
        assert r["frames"] is None and r["cep95_vs_truth_m"] is None

    csv_rows = list(csv.DictReader(open(out / "fleet_summary.csv", encoding="utf-8")))
    summary = json.loads((out / "fleet_summary.json").read_text())
    assert (summary["drives"], summary["ok"], summary["failed"]) == (4, 2, 2)
    assert list(csv_rows[0]) == SUMMARY_FIELDS
    for row, csv_row, json_row in zip(rows, csv_rows, summary["rows"]):
        assert json_row == row
        assert csv_row["status"] == row["status"] and csv_row["error"] == (row["error"] or "")
        if row["status"] != "ok":
            assert not (out / row["drive"]).exists()
            continue
        report = json.loads((out / row["drive"] / "report.json").read_text())
        expected = figures(report)
        assert report["visual_fixes"] > 0 and expected["cep95_vs_truth_m"] is not None
        assert {k: row[k] for k in expected} == expected  # the same numbers, bit for bit
        for k, v in expected.items():
            assert (float(csv_row[k]) if isinstance(v, float) else int(csv_row[k])) == v, k
        assert row["wall_s"] > 0 and csv_row["host"]
    # Each drive's outputs are the replay command's: equal to a direct vgps.replay.
    vgps.replay(good_b, tmp_path / "direct_b", threads=1)
    for name in ["fixes.csv", "report.json", "track.gpx"]:
        assert (out / "good_b" / name).read_bytes() == (tmp_path / "direct_b" / name).read_bytes()
    assert not [p for p in os.listdir(out) if p.startswith(".")]  # no temporary file left


def test_a_worker_killed_mid_task_is_retried(ray_local, drives, tmp_path):
    from vgps.fleet import replay_many

    good_a = drives[0]
    (ray_local / "good_a.armed").touch()  # the task's worker kills itself once (os._exit)
    rows = replay_many([good_a], tmp_path / "retried", max_retries=1, progress=False)
    assert (ray_local / "good_a.fired").exists()
    assert rows[0]["status"] == "ok", rows[0]["error"]
    assert (tmp_path / "retried" / "good_a" / "report.json").exists()

    # Without retries the dead worker is a failed row naming the drive.
    (ray_local / "good_a.armed").touch()
    rows = replay_many([good_a], tmp_path / "not_retried", max_retries=0, progress=False)
    assert rows[0]["status"] == "failed"
    assert str(good_a) in rows[0]["error"] and "Worker" in rows[0]["error"], rows[0]["error"]


def test_duplicate_drive_names_are_refused_before_any_task(drives, tmp_path):
    pytest.importorskip("ray", reason="Ray is not installed; fleet tests skipped")
    from vgps.fleet import replay_many

    other = tmp_path / "elsewhere" / "good_a"
    with pytest.raises(ValueError, match="two drives have the name 'good_a'"):
        replay_many([drives[0], other], tmp_path / "out", progress=False)
    assert not (tmp_path / "out" / "fleet_summary.csv").exists()


def test_command_line_with_a_drive_list(ray_local, drives, tmp_path, capsys):
    from vgps.fleet import main

    good_a, _, broken = drives
    listing = tmp_path / "drives.txt"
    listing.write_text(f"{good_a}\n\n{broken}\n")
    out = tmp_path / "cli"
    assert main(["--out", str(out), f"@{listing}", "--no-progress", "--no-imu"]) == 1
    captured = capsys.readouterr()
    assert "1/2 drives ok" in captured.out
    assert f"failed: {broken}" in captured.err
    summary = json.loads((out / "fleet_summary.json").read_text())
    assert [r["status"] for r in summary["rows"]] == ["ok", "failed"]
