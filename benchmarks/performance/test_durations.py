"""Where the test suite's time goes: the slowest tests of JUnit reports, side by side.

Usage:
    python3 benchmarks/performance/test_durations.py NAME=REPORT.xml [NAME=REPORT.xml ...]
        [--top 30] [--out test_durations]

Each report is a pass of pytest with --junitxml (`make test JUNIT=DIR` writes one per pass;
under xdist a test's time is its worker's). The first report orders the table: its `top`
slowest tests, with their time in every report ('-' where a report does not hold the test),
then each report's count of tests and summed time. Writes benchmarks/results/<out>.md and
.json. The times include set-up and tear-down (module fixtures fall on the module's first test).
"""
import argparse
import importlib.util
import json
import pathlib
import xml.etree.ElementTree as ET

ROOT = pathlib.Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"
_spec = importlib.util.spec_from_file_location("tally", ROOT / ".ci" / "tally.py")
tally = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tally)


def durations(path: pathlib.Path) -> dict[str, float]:
    """test id -> seconds (set-up, call and tear-down), from one JUnit report."""
    times = {}
    for case in ET.parse(path).getroot().iter("testcase"):
        name = tally.GROUP_SUFFIX.sub("", case.get("name"))
        module = case.get("classname").replace(".", "/") + ".py"
        times[f"{module}::{name}"] = float(case.get("time", 0.0))
    return times


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("reports", nargs="+", help="NAME=REPORT.xml")
    parser.add_argument("--top", type=int, default=30)
    parser.add_argument("--out", default="test_durations")
    args = parser.parse_args()
    named = [item.split("=", 1) for item in args.reports]
    runs = {name: durations(pathlib.Path(path)) for name, path in named}
    first = runs[named[0][0]]
    slowest = sorted(first, key=first.get, reverse=True)[:args.top]
    header = "| test | " + " | ".join(f"{name} (s)" for name, _ in named) + " |"
    lines = [header, "|---|" + "---:|" * len(named)]
    for test in slowest:
        cells = [f"{runs[name][test]:.1f}" if test in runs[name] else "-" for name, _ in named]
        lines.append(f"| `{test.removeprefix('tests/')}` | " + " | ".join(cells) + " |")
    lines.append("")
    lines.append("| report | tests | summed time (s) |")
    lines.append("|---|---:|---:|")
    for name, _ in named:
        lines.append(f"| {name} | {len(runs[name])} | {sum(runs[name].values()):.0f} |")
    text = "\n".join(lines) + "\n"
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.out}.md").write_text(text)
    (RESULTS / f"{args.out}.json").write_text(json.dumps(
        {"reports": dict(named), "slowest": {t: {n: runs[n].get(t) for n, _ in named}
                                            for t in slowest},
         "totals": {n: {"tests": len(runs[n]), "seconds": sum(runs[n].values())}
                    for n, _ in named}}, indent=1))
    print(text)


if __name__ == "__main__":
    main()
