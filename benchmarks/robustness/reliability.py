"""The fault campaign behind docs/reliability.md: kill -9 of a real rank process at 20 moments
on 1 and on 2 ranks, signals, a full disk, a folder in use, an error on one rank, damaged
checkpoints. Each case records the exit code, how long the job took to end, what the folder
held (step records, XDMF steps read back, checkpoint) and whether --restart completed the
time series once (tests/helpers.check_folder checks every file).

    python benchmarks/robustness/reliability.py --part kill1  # kill -9, 1 rank (~3 min)
    python benchmarks/robustness/reliability.py --part kill2  # kill -9, 2 ranks (~5 min)
    python benchmarks/robustness/reliability.py --part other  # signals, disk, folder,
                                                              # checkpoints
    python benchmarks/robustness/reliability.py --part paths  # links, FIFOs, records with
                                                              # holes, runs inside runs

Results: benchmarks/results/reliability_<part>.json and .md (one table row per case).
"""
import argparse
import json
import os
import pathlib
import random
import shutil
import signal
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402
from helpers import (alive, block_rank0_file, check_folder, end, grow_tmpfs,  # noqa: E402
                     kill_a_rank, mount_tmpfs, rank_pids, run_cli, run_paper, start_paper,
                     unmount, wait_for)

STEPS = 60
#: Steps completed before the kill (0: during set-up, before the first step is written).
MOMENTS = [0, 1, 2, 3, 5, 7, 10, 13, 16, 20, 24, 28, 32, 36, 40, 44, 48, 52, 56, 59]


def outcome(out, ranks, steps, code, seconds, note=""):
    """Check the folder, restart, check the whole series; a row of the table."""
    row = {"exit": code, "ended_s": round(seconds, 2), "note": note}
    try:
        row.update(check_folder(out))
        row["left_ok"] = True
    except AssertionError as err:
        row.update(left_ok=False, left_error=str(err))
        return row
    restart = run_paper(ranks, out, steps, 16, "--restart")
    if restart.returncode == 2 and "no checkpoint" in restart.stderr:
        row["restart"] = "refused: no checkpoint (no step completed); rerun with --overwrite"
        restart = run_paper(ranks, out, steps, 16, "--overwrite")
    else:
        row["restart"] = f"exit {restart.returncode}"
    try:
        check_folder(out, complete_steps=steps + 1, k=1.0 / steps)
        row["complete_after"] = restart.returncode == 0
    except AssertionError as err:
        row.update(complete_after=False, complete_error=str(err))
    return row


def kill_campaign(ranks, root):
    rows = []
    rng = random.Random(11)
    for i, moment in enumerate(MOMENTS):
        out = root / f"kill{ranks}-{i}"
        victim = i % ranks
        proc = start_paper(ranks, out, STEPS)
        pids = rank_pids(out, proc, ranks)
        if moment and not wait_for(out, proc, moment):
            rows.append({"case": f"kill -9 rank {victim} after {moment} steps",
                         "note": "run ended first"})
            continue
        time.sleep(rng.uniform(0.0, 0.02))        # anywhere inside the next step
        os.kill(pids[victim], signal.SIGKILL)
        code, seconds = end(proc)
        row = outcome(out, ranks, STEPS, code, seconds)
        row["case"] = f"kill -9 rank {victim} of {ranks} after {moment} steps"
        row["ranks_left"] = sum(alive(p, 1.0) for p in pids)
        rows.append(row)
        print(json.dumps(row), flush=True)
        shutil.rmtree(out, ignore_errors=True)
    return rows


def signal_cases(root):
    rows = []
    cases = [(1, "rank", signal.SIGTERM, 5), (1, "rank", signal.SIGINT, 20),
             (2, "mpirun", signal.SIGTERM, 5), (2, "rank 1", signal.SIGTERM, 20),
             (2, "rank 0", signal.SIGINT, 30)]
    for ranks, target, sig, moment in cases:
        out = root / f"sig-{ranks}-{target.replace(' ', '')}-{sig.name}"
        proc = start_paper(ranks, out, 200)
        pids = rank_pids(out, proc, ranks)
        wait_for(out, proc, moment)
        pid = proc.pid if target == "mpirun" else pids[-1 if target == "rank 1" else 0]
        os.kill(pid, sig)
        code, seconds = end(proc)
        err = pathlib.Path(f"{out}.err").read_text()
        row = outcome(out, ranks, 200, code, seconds,
                      note=f"messages: {err.count('stopped by')}")
        row["case"] = f"{sig.name} to {target} ({ranks} rank(s)) after {moment} steps"
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def disk_cases(root):
    rows = []
    for ranks in (1, 2):
        disk = root / f"disk{ranks}"
        disk.mkdir()
        if not mount_tmpfs(disk, "400k"):
            rows.append({"case": f"full disk ({ranks} rank(s))", "note": "no tmpfs (not root)"})
            continue
        try:
            tick = time.time()
            proc = run_paper(ranks, disk / "run", 40, 8)
            seconds = time.time() - tick
            row = {"case": f"full disk, 400 kB tmpfs ({ranks} rank(s))",
                   "exit": proc.returncode, "ended_s": round(seconds, 2),
                   "note": next((line[:120] for line in proc.stderr.splitlines()
                                 if line.startswith("contactvisco:")), "")}
            row.update(check_folder(disk / "run"), left_ok=True)
            grow_tmpfs(disk, "20m")
            restart = run_paper(ranks, disk / "run", 40, 8, "--restart")
            row["restart"] = f"exit {restart.returncode} after the disk was grown"
            check_folder(disk / "run", complete_steps=41, k=1 / 40)
            row["complete_after"] = restart.returncode == 0
        except AssertionError as err:
            row["error"] = str(err)
        finally:
            unmount(disk)
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def folder_cases(root):
    rows = []
    out = root / "busy"
    proc = start_paper(2, out, 400)
    pids = rank_pids(out, proc, 2)
    for ranks in (1, 2):
        tick = time.time()
        second = run_paper(ranks, out, 400)
        rows.append({"case": f"second run ({ranks} rank(s)) into a folder in use",
                     "exit": second.returncode, "ended_s": round(time.time() - tick, 2),
                     "note": second.stderr.strip()[:160]})
    os.kill(pids[0], signal.SIGKILL)
    end(proc)
    again = run_paper(1, out, 400)
    rows.append({"case": "new run into a folder with an earlier run's files (lock freed by "
                 "kill -9)", "exit": again.returncode, "note": again.stderr.strip()[:160]})
    over = run_paper(1, out, 4, 8, "--overwrite")
    rows.append({"case": "--overwrite", "exit": over.returncode,
                 "note": "earlier files replaced"})
    for r in rows:
        print(json.dumps(r), flush=True)
    return rows


def one_rank_error(root):
    out = root / "onerank"
    run_paper(1, out, 3, 8)
    block_rank0_file(out)
    tick = time.time()
    proc = run_paper(2, out, 3, 8, "--restart")
    row = {"case": "error on rank 0 only (its snapshots.npz is damaged), rank 1 in a "
           "collective", "exit": proc.returncode, "ended_s": round(time.time() - tick, 2),
           "note": f"messages: {proc.stderr.count('not a readable .npz archive')}"}
    print(json.dumps(row), flush=True)
    return [row]


def checkpoint_cases(root):
    """Damaged or edited checkpoints through the command line: exit 2 naming the file."""
    import test_checkpoint_checks as cases
    base = root / "ckpt"
    assert run_paper(1, base, 3, 4).returncode == 0
    rows = []
    for name, (damage, file, words) in sorted(cases.CASES.items()):
        target = root / f"ckpt-{name.replace(' ', '_')}"
        shutil.copytree(base, target)
        damage(target)
        proc = run_paper(1, target, 3, 4, "--restart")
        rows.append({"case": f"checkpoint: {name}", "exit": proc.returncode,
                     "note": proc.stderr.strip().replace(str(root), "")[:200],
                     "names_file": file in proc.stderr, "says_what": words in proc.stderr})
        print(json.dumps(rows[-1]), flush=True)
    other = run_paper(1, base, 3, 4, "--restart", "--set", "contact.mu=0.3")
    rows.append({"case": "restart with another scene", "exit": other.returncode,
                 "note": other.stderr.strip()[-120:]})
    output_only = run_paper(1, base, 3, 4, "--restart", "--set", "output.xdmf=false")
    rows.append({"case": "restart with other output options", "exit": output_only.returncode,
                 "note": "allowed"})
    return rows


def paths_cases(root):
    """The cases of tests/robustness/test_paths.py through the command line, on 1 and 2
    ranks: a symbolic link at each name a restart writes, a FIFO at each name it reads, the
    record files damaged after a kill -9. Each row: the exit code, the time, whether the
    message names the path, whether the file outside is unchanged."""
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "tests" /
                           "robustness"))
    import test_paths as cases
    small = [a for o in cases.SMALL for a in ("--set", o)]
    base = root / "paths-base"
    assert run_cli("run", "paper", *small, "--quiet", "--out", base).returncode == 0
    outside = root / "outside"
    outside.mkdir()
    (outside / "victim").write_text("keep")
    rows = []

    def restart(ranks, name, target, kind):
        tick = time.time()
        proc = run_cli("run", "paper", *small, "--quiet", "--out", target, "--restart",
                       ranks=ranks, timeout=120)
        rows.append({"case": f"{kind} at {name}, --restart ({ranks} rank(s))",
                     "exit": proc.returncode, "ended_s": round(time.time() - tick, 2),
                     "note": proc.stderr.strip().replace(str(root), "")[:160],
                     "names_file": name in proc.stderr,
                     "outside_kept": (outside / "victim").read_text() == "keep"
                     and sorted(p.name for p in outside.iterdir()) == ["victim"]})
        print(json.dumps(rows[-1]), flush=True)

    for i, name in enumerate(cases.LINKED_FILES):
        target = root / f"link-{i}"
        shutil.copytree(base, target, symlinks=True)
        (target / name).unlink(missing_ok=True)
        (target / name).symlink_to(outside / "victim")
        restart(1, name, target, "symbolic link")
    for ranks in (1, 2):
        for i, name in enumerate(cases.FIFO_RESTART):
            target = root / f"fifo-{ranks}-{i}"
            shutil.copytree(base, target, symlinks=True)
            cases.fifo(target / name)
            restart(ranks, name, target, "FIFO")
    for ranks in (1, 2):
        killed = root / f"killed-{ranks}"
        proc = start_paper(ranks, killed, cases.KILL_STEPS, 16, "--set",
                           "output.checkpoint_every=5")
        kill_a_rank(killed, proc, ranks, ranks - 1, cases.KILL_AT)
        for i, (case, (name, damage)) in enumerate(sorted(cases.DAMAGE.items())):
            target = root / f"holes-{ranks}-{i}"
            shutil.copytree(killed, target)
            damage(target)
            tick = time.time()
            proc = cases.restart_killed(ranks, target)
            rows.append({"case": f"after kill -9: {case}, --restart ({ranks} rank(s))",
                         "exit": proc.returncode, "ended_s": round(time.time() - tick, 2),
                         "note": proc.stderr.strip().replace(str(root), "")[:160],
                         "names_file": name in proc.stderr})
            print(json.dumps(rows[-1]), flush=True)
    return rows


def table(rows) -> str:
    keys = ["case", "exit", "ended_s", "records", "fields", "checkpoint", "left_ok", "restart",
            "complete_after", "names_file", "outside_kept", "note"]
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for r in rows:
        lines.append("| " + " | ".join(str(r.get(k, "")).replace("|", "/") for k in keys)
                     + " |")
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--part", choices=["kill1", "kill2", "other", "paths"], required=True)
    args = parser.parse_args()
    root = pathlib.Path(tempfile.mkdtemp(prefix="cv-reliability-"))
    try:
        if args.part == "kill1":
            rows = kill_campaign(1, root)
        elif args.part == "kill2":
            rows = kill_campaign(2, root)
        elif args.part == "paths":
            rows = paths_cases(root)
        else:
            rows = (signal_cases(root) + disk_cases(root) + folder_cases(root)
                    + one_rank_error(root) + checkpoint_cases(root))
    finally:
        shutil.rmtree(root, ignore_errors=True)
    write_results(f"reliability_{args.part}", rows, table(rows).splitlines())


if __name__ == "__main__":
    main()
