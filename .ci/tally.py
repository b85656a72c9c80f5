"""The tiers of a CI run, counted from the JUnit reports of its passes (`make ... JUNIT=DIR`).

Usage: python3 .ci/tally.py DIR [PYTHON]

PYTHON (default: .venv/bin/python) collects the suite three times (every test, the tests marked
slow, the tests marked mpi and not processes); each report DIR/<stack>-<pass>.xml then says which
tests passed, were skipped or failed. Printed: a table of the passes; whether the 1-rank tiers
(not slow, slow) add up to the whole suite; every in-process mpi test that did not pass on
2 ranks on each route; the tests that ran in no pass at all. Exit 1 when a report is missing, a
test failed, or the tiers do not add up; the last line is the plain closing count of every test
run in every pass ('N passed, N failed, N skipped')."""
import pathlib
import re
import subprocess
import sys
import xml.etree.ElementTree as ET

PASSES = [("debian-1rank", "Debian, 1 rank, not slow"), ("debian-slow", "Debian, 1 rank, slow"),
          ("debian-2ranks", "Debian, 2 ranks, mpi"), ("pip-1rank", "PyPI, 1 rank, not slow"),
          ("pip-2ranks", "PyPI, 2 ranks, mpi")]
# pytest-xdist's loadgroup adds "@group" to a test's id (tests/conftest.py names the groups).
GROUP_SUFFIX = re.compile(r"@(processes|test_\w+)$")


def collect(python: str, marker: str | None) -> set[str]:
    """The test ids pytest collects (with -m marker if given)."""
    command = [python, "-m", "pytest", "--collect-only", "-q", "tests"]
    if marker:
        command[4:4] = ["-m", marker]
    out = subprocess.run(command, capture_output=True, text=True, check=True).stdout
    return {line.strip() for line in out.splitlines() if "::" in line}


def outcomes(path: pathlib.Path) -> dict[str, str]:
    """test id -> passed, skipped or failed, from one JUnit report."""
    result = {}
    for case in ET.parse(path).getroot().iter("testcase"):
        name = GROUP_SUFFIX.sub("", case.get("name"))
        module = case.get("classname").replace(".", "/") + ".py"
        status = "passed"
        for child in case:
            if child.tag == "skipped":
                status = "skipped"
            elif child.tag in ("failure", "error"):
                status = "failed"
        result[f"{module}::{name}"] = status
    return result


def main(folder: str, python: str = ".venv/bin/python") -> int:
    folder = pathlib.Path(folder)
    suite, slow = collect(python, None), collect(python, "slow")
    in_process_mpi = collect(python, "mpi and not processes")
    reports, problems = {}, []
    for name, label in PASSES:
        path = folder / f"{name}.xml"
        if path.exists():
            reports[name] = outcomes(path)
        else:
            problems.append(f"no report {path}")
    print(f"{len(suite)} tests collected; {len(slow)} marked slow; "
          f"{len(in_process_mpi)} marked mpi and run on 2 ranks in-process")
    print(f"{'pass':28s} {'tests':>6s} {'passed':>7s} {'skipped':>8s} {'failed':>7s}")
    totals = {"passed": 0, "failed": 0, "skipped": 0}
    for name, label in PASSES:
        if name not in reports:
            continue
        counts = {key: sum(1 for s in reports[name].values() if s == key) for key in totals}
        for key in totals:
            totals[key] += counts[key]
        print(f"{label:28s} {len(reports[name]):6d} {counts['passed']:7d} "
              f"{counts['skipped']:8d} {counts['failed']:7d}")
    if "debian-1rank" in reports and "debian-slow" in reports:
        fast, slow_run = set(reports["debian-1rank"]), set(reports["debian-slow"])
        print(f"1-rank tiers: {len(fast)} not slow + {len(slow_run)} slow = "
              f"{len(fast) + len(slow_run)} of {len(suite)} collected")
        if fast | slow_run != suite or fast & slow_run:
            problems.append(f"the 1-rank tiers do not add up to the suite: missing "
                            f"{sorted(suite - fast - slow_run)[:10]}, in both "
                            f"{sorted(fast & slow_run)[:10]}")
    for stack in ("debian", "pip"):
        report = reports.get(f"{stack}-2ranks", {})
        not_passed = sorted(t for t in in_process_mpi if report.get(t) != "passed")
        print(f"{stack}: {len(in_process_mpi) - len(not_passed)} of {len(in_process_mpi)} "
              f"in-process mpi tests passed on 2 ranks")
        for test in not_passed:
            print(f"  {report.get(test, 'not run')}: {test}")
    ran = {t for r in reports.values() for t, s in r.items() if s == "passed"}
    never = sorted(suite - ran)
    print(f"passed in at least one pass: {len(suite) - len(never)} of {len(suite)}")
    for test in never:
        print(f"  passed in no pass (skipped where collected): {test}")
    if totals["failed"]:
        problems.append(f"{totals['failed']} failed")
    for problem in problems:
        print(f"tally: {problem}")
    closing = f"tests: {totals['passed']} passed, {totals['failed']} failed, " \
              f"{totals['skipped']} skipped"
    (folder / "closing.txt").write_text(closing + "\n")
    print(closing)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
