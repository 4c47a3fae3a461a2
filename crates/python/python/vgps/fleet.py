"""Fleet reprocessing on Ray: one Ray task per drive, one summary for the fleet.

``replay_many(drives, out)`` replays every drive with :func:`vgps.replay` (the command
line's own code, GIL released) in its own Ray task, writes each drive's outputs under
``out/<drive name>/`` exactly as ``vgps replay`` does, and one fleet summary
``out/fleet_summary.csv`` + ``out/fleet_summary.json``: per drive, frames, fix rate,
CEP50/CEP95 against truth and against satellite GPS (taken from the drive's
``report.json``), wall time, and ``ok`` or ``failed`` with an error message naming the drive.
A failed drive never stops the others.

The same call runs on a laptop (``ray.init()``, or nothing: a local instance is started)
and on a Ray cluster (``ray.init(address="ray://head:10001")``, or ``RAY_ADDRESS``, or a
``ray job submit -- python -m vgps.fleet ...``); on a cluster the drives and ``out`` must be
on a file system every node mounts at the same path.

Ray is an optional dependency (``pip install "vgps[fleet]"``): ``import vgps`` never imports
it, and this module imports it only when ``replay_many`` is called. A progress bar uses
``tqdm`` when it is installed, a plain line per finished drive otherwise.

Example::

    >>> import ray, vgps.fleet                                          # doctest: +SKIP
    >>> ray.init()                                                      # doctest: +SKIP
    >>> rows = vgps.fleet.replay_many(["drives/a", "drives/b"], "out")  # doctest: +SKIP
    >>> [(r["drive"], r["status"], r["cep95_vs_truth_m"]) for r in rows]  # doctest: +SKIP
"""

from __future__ import annotations

import csv
import io
import json
import os
import socket
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Dict, Iterable, List, Optional, Sequence, Union

__all__ = ["SUMMARY_FIELDS", "replay_many", "summary_row"]

#: Columns of ``fleet_summary.csv`` (and keys of each row of ``fleet_summary.json``), in
#: order. Figures a drive's report does not have (no truth, no satellite GPS) are empty in
#: the CSV and ``null`` in the JSON.
SUMMARY_FIELDS = [
    "drive",  # the drive folder's name: its outputs are under out/<drive>/
    "status",  # ok | failed
    "frames",  # report.json: frames
    "visual_fixes",  # report.json: visual_fixes
    "fix_rate",  # report.json: visual_fix_rate
    "cep50_vs_truth_m",  # report.json: visual_vs_truth.horizontal_m.cep50
    "cep95_vs_truth_m",  # report.json: visual_vs_truth.horizontal_m.cep95
    "cep50_vs_gnss_m",  # report.json: visual_vs_gnss.horizontal_m.cep50
    "cep95_vs_gnss_m",  # report.json: visual_vs_gnss.horizontal_m.cep95
    "gnss_cep50_vs_truth_m",  # report.json: gnss_vs_truth.horizontal_m.cep50
    "gnss_cep95_vs_truth_m",  # report.json: gnss_vs_truth.horizontal_m.cep95
    "wall_s",  # the task's wall time (the replay and reading its report)
    "host",  # the node that ran it
    "path",  # the drive folder as given (made absolute)
    "error",  # why it failed, naming the drive; empty when ok
]

# Test hook (used by crates/python/tests/test_fleet.py): when this variable names a folder
# holding `<drive name>.armed`, the task for that drive renames it to `.fired` and kills its
# own worker process, once, as a crashed or OOM-killed worker would die.
_CRASH_HOOK_ENV = "_VGPS_FLEET_TEST_CRASH_DIR"
_CRASH_EXIT_CODE = 70
# Ray's worker process priority (its default is nice 15), read when Ray starts its raylet.
_NICENESS_ENV = "RAY_worker_niceness"


def drive_name(drive: Union[str, "os.PathLike[str]"]) -> str:
    """The name of a drive's output folder: the drive folder's last component."""
    name = Path(os.path.abspath(os.fspath(drive))).name
    return name or "drive"


def summary_row(report: Dict[str, Any]) -> Dict[str, Any]:
    """The summary figures of one drive, read from its ``report.json`` (as a dict)."""

    def horizontal(section: str, stat: str) -> Optional[float]:
        block = report.get(section) or {}
        return (block.get("horizontal_m") or {}).get(stat)

    return {
        "frames": report.get("frames"),
        "visual_fixes": report.get("visual_fixes"),
        "fix_rate": report.get("visual_fix_rate"),
        "cep50_vs_truth_m": horizontal("visual_vs_truth", "cep50"),
        "cep95_vs_truth_m": horizontal("visual_vs_truth", "cep95"),
        "cep50_vs_gnss_m": horizontal("visual_vs_gnss", "cep50"),
        "cep95_vs_gnss_m": horizontal("visual_vs_gnss", "cep95"),
        "gnss_cep50_vs_truth_m": horizontal("gnss_vs_truth", "cep50"),
        "gnss_cep95_vs_truth_m": horizontal("gnss_vs_truth", "cep95"),
    }


def _naming(drive: str, message: str) -> str:
    """``message``, prefixed with the drive unless it already names it."""
    message = message.strip() or "failed without a message"
    return message if drive in message else f"{drive}: {message}"


def _crash_hook(name: str) -> None:
    folder = os.environ.get(_CRASH_HOOK_ENV)
    if not folder:
        return
    armed = os.path.join(folder, name + ".armed")
    try:
        os.replace(armed, os.path.join(folder, name + ".fired"))
    except OSError:
        return
    os._exit(_CRASH_EXIT_CODE)


def _replay_one(drive: str, out_dir: str, options: Dict[str, Any]) -> Dict[str, Any]:
    """The Ray task: replays one drive; a bad drive is a ``failed`` row, not an exception.

    Exceptions other than ``VgpsError`` (an I/O error reading the report back, …) propagate,
    so that Ray retries them when ``retry_exceptions`` says so.
    """
    import vgps

    name = drive_name(drive)
    _crash_hook(name)
    row: Dict[str, Any] = {k: None for k in SUMMARY_FIELDS}
    row.update(drive=name, path=drive, host=socket.gethostname())
    start = time.perf_counter()
    try:
        report = vgps.replay(drive, out_dir, **options)
    except vgps.VgpsError as e:
        row.update(status="failed", error=_naming(drive, str(e)))
    else:
        row.update(summary_row(report), status="ok")
    row["wall_s"] = time.perf_counter() - start
    return row


def _ray_error_message(error: BaseException) -> str:
    """A one-line reason from a Ray error (a task's exception, a dead worker, …)."""
    cause = getattr(error, "cause", None)
    if cause is not None and cause is not error:
        return f"{type(cause).__name__}: {cause}".splitlines()[0]
    lines = [line for line in str(error).splitlines() if line.strip()]
    return f"{type(error).__name__}: {lines[0] if lines else ''}"


class _Progress:
    """tqdm when it is installed, else one plain line per finished drive (stderr)."""

    def __init__(self, total: int, enabled: bool):
        self.total, self.done, self.failed, self.bar = total, 0, 0, None
        self.enabled = enabled
        if enabled:
            try:
                from tqdm.auto import tqdm
            except ImportError:
                pass
            else:
                self.bar = tqdm(total=total, desc="vgps fleet", unit="drive")

    def update(self, row: Dict[str, Any]) -> None:
        self.done += 1
        self.failed += row["status"] != "ok"
        if not self.enabled:
            return
        if self.bar is not None:
            self.bar.set_postfix(failed=self.failed, refresh=False)
            self.bar.update(1)
        else:
            wall = "" if row["wall_s"] is None else f", {row['wall_s']:.1f} s"
            print(
                f"vgps fleet: {self.done}/{self.total} drives done, {self.failed} failed "
                f"({row['drive']}: {row['status']}{wall})",
                file=sys.stderr,
                flush=True,
            )

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _write_atomic(path: Path, text: str) -> None:
    """Writes ``text`` to ``path`` through a temporary file in the same folder and
    ``os.replace``: a reader sees the old file or the new one, never a part."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.tmp-", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_summary(out: Union[str, "os.PathLike[str]"], rows: Sequence[Dict[str, Any]],
                  wall_s: Optional[float] = None) -> None:
    """Writes ``fleet_summary.csv`` and ``fleet_summary.json`` under ``out``, atomically."""
    out = Path(out)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=SUMMARY_FIELDS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        # repr() of a float reads back to the same float: the CSV holds report.json's numbers.
        writer.writerow({k: ("" if row.get(k) is None else
                             repr(row[k]) if isinstance(row[k], float) else row[k])
                         for k in SUMMARY_FIELDS})
    _write_atomic(out / "fleet_summary.csv", buf.getvalue())
    summary = {
        "drives": len(rows),
        "ok": sum(r["status"] == "ok" for r in rows),
        "failed": sum(r["status"] != "ok" for r in rows),
        "wall_s": wall_s,
        "rows": [{k: row.get(k) for k in SUMMARY_FIELDS} for row in rows],
    }
    _write_atomic(out / "fleet_summary.json", json.dumps(summary, indent=2) + "\n")


def _import_ray():
    try:
        import ray
    except ImportError as e:
        raise ImportError(
            "vgps.fleet needs Ray: pip install \"vgps[fleet]\" (or pip install ray)"
        ) from e
    return ray


def _init_local(ray) -> None:
    """``ray.init()``, with the tasks at the driver's priority: Ray runs its workers at nice
    15 by default, which on a machine shared with other work (a laptop, a CI runner) makes
    a replay several times slower than the same command run by hand. ``RAY_worker_niceness``
    set by the caller wins."""
    previous = os.environ.get(_NICENESS_ENV)
    os.environ.setdefault(_NICENESS_ENV, "0")
    try:
        ray.init()
    finally:
        if previous is None:
            os.environ.pop(_NICENESS_ENV, None)


def replay_many(
    drives: Iterable[Union[str, "os.PathLike[str]"]],
    out: Union[str, "os.PathLike[str]"],
    *,
    num_cpus: float = 1,
    memory: Optional[int] = None,
    max_retries: int = 3,
    retry_exceptions: Union[bool, Sequence[type]] = False,
    progress: bool = True,
    ray_options: Optional[Dict[str, Any]] = None,
    **options: Any,
) -> List[Dict[str, Any]]:
    """Replays every drive in its own Ray task; returns the summary rows in ``drives`` order.

    Writes each drive's outputs under ``out/<drive name>/`` (``fixes.csv``, ``report.json``,
    ``report.html``, tracks, …, as ``vgps replay`` does) and ``out/fleet_summary.csv`` +
    ``out/fleet_summary.json`` (columns :data:`SUMMARY_FIELDS`), both written atomically.

    Drive folders must have distinct names (``ValueError`` otherwise, before any task).
    A missing or corrupt drive, or a task that still fails after its retries, is a row with
    ``status="failed"`` and ``error`` naming the drive; the other drives go on.

    Resource hints and retries (Ray's task options):

    - ``num_cpus``: CPUs reserved per task (default 1); also the replay's ``threads``
      unless ``threads=`` is given. ``memory``: bytes reserved per task (default none).
    - ``max_retries``: how often a task is re-run when its worker process dies (a crash,
      the OOM killer, a lost node); default 3.
    - ``retry_exceptions``: also re-run a task that raised (``True``, or a list of exception
      types). A bad drive (``vgps.VgpsError``) is never retried: it would fail again.
    - ``ray_options``: any other ``.options()`` of the task (``resources``,
      ``scheduling_strategy``, ``runtime_env``, …).

    Other keyword options are ``vgps.replay``'s (the command's flags: ``from_images=True``,
    ``no_gnss_prior=True``, …) and apply to every drive. Ray is started locally
    (``ray.init()``, tasks at normal priority) if no instance is connected yet; when you
    start it yourself on a shared machine, ``RAY_worker_niceness=0`` in the environment
    gives the tasks the priority of a command run by hand (Ray's default is nice 15).
    """
    ray = _import_ray()
    drives = [os.path.abspath(os.fspath(d)) for d in drives]
    names = [drive_name(d) for d in drives]
    seen: Dict[str, str] = {}
    for drive, name in zip(drives, names):
        if name in seen:
            raise ValueError(
                f"two drives have the name {name!r} ({seen[name]} and {drive}): their outputs "
                f"would both go to {os.path.join(os.fspath(out), name)}"
            )
        seen[name] = drive
    if "fleet_summary.csv" in seen or "fleet_summary.json" in seen:
        raise ValueError("a drive folder is named like the fleet summary")
    out = Path(os.path.abspath(os.fspath(out)))
    out.mkdir(parents=True, exist_ok=True)
    options.setdefault("threads", max(1, int(num_cpus)))
    task_options: Dict[str, Any] = dict(
        num_cpus=num_cpus, max_retries=max_retries, retry_exceptions=retry_exceptions
    )
    if memory is not None:
        task_options["memory"] = memory
    task_options.update(ray_options or {})

    start = time.perf_counter()
    if not ray.is_initialized():
        _init_local(ray)
    task = ray.remote(_replay_one).options(**task_options)
    pending = {
        task.remote(drive, str(out / name), options): k
        for k, (drive, name) in enumerate(zip(drives, names))
    }
    rows: List[Optional[Dict[str, Any]]] = [None] * len(drives)
    bar = _Progress(len(drives), progress)
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                k = pending.pop(ref)
                try:
                    row = ray.get(ref)
                except Exception as e:  # a task that raised, a dead worker, a lost node
                    row = {key: None for key in SUMMARY_FIELDS}
                    row.update(drive=names[k], path=drives[k], status="failed",
                               error=_naming(drives[k], _ray_error_message(e)))
                rows[k] = row
                bar.update(row)
    finally:
        bar.close()
    done = [r for r in rows if r is not None]
    write_summary(out, done, wall_s=time.perf_counter() - start)
    return done


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``python -m vgps.fleet --out OUT DRIVE...`` (e.g. under ``ray job submit``)."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m vgps.fleet",
        description="Replay many drives on Ray, one task per drive, and write a fleet summary.",
    )
    parser.add_argument("drives", nargs="+", help="drive folders (or @FILE: one per line)")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--address", help="Ray address (default: RAY_ADDRESS, else local)")
    parser.add_argument("--num-cpus", type=float, default=1, help="CPUs per task")
    parser.add_argument("--max-retries", type=int, default=3)
    parser.add_argument("--no-progress", action="store_true")
    args, replay_flags = parser.parse_known_args(argv)
    drives: List[str] = []
    for d in args.drives:
        if d.startswith("@"):
            with open(d[1:], encoding="utf-8") as f:
                drives += [line.strip() for line in f if line.strip()]
        else:
            drives.append(d)
    options: Dict[str, Any] = {}
    for flag in replay_flags:  # --from-images, --no-gnss-prior, … (bare flags only)
        if not flag.startswith("--") or "=" in flag:
            parser.error(f"unsupported replay option {flag!r} (bare --flags only)")
        options[flag[2:].replace("-", "_")] = True
    ray = _import_ray()
    if args.address or os.environ.get("RAY_ADDRESS"):
        ray.init(address=args.address)  # a cluster (inside `ray job submit`: its own)
    rows = replay_many(drives, args.out, num_cpus=args.num_cpus, max_retries=args.max_retries,
                       progress=not args.no_progress, **options)
    failed = [r for r in rows if r["status"] != "ok"]
    for r in failed:
        print(f"failed: {r['error']}", file=sys.stderr)
    print(f"{len(rows) - len(failed)}/{len(rows)} drives ok; summary in "
          f"{os.path.join(args.out, 'fleet_summary.csv')}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
