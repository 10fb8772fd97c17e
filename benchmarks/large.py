"""Run the large-record benchmarks (benchmarks/suite/test_bench_large.py) and write
results/large_inputs.md with the raw pytest-benchmark JSON beside it.

    python -m magbench.benchmarks.large [--out results]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from magbench.benchmarks.speed import suite_file

COMMAND = "python -m magbench.benchmarks.large"
TARGETS = {("calibrate", 2_000_000): (10.0, 800.0), ("diagnose", 1_000_000): (60.0, None)}
"""Issue targets: (whole-process seconds, peak MiB) for the command at that many rows."""


def run(out_dir: Path) -> Path:
    raw = (out_dir / "benchmarks" / "large.json").resolve()
    raw.parent.mkdir(parents=True, exist_ok=True)
    suite = suite_file("test_bench_large.py")
    subprocess.run([sys.executable, "-m", "pytest", str(suite), "-q", "-p", "no:cacheprovider",
                    f"--benchmark-json={raw}"], check=True, cwd=suite.parent)
    return raw


def report(raw: Path, out: Path) -> str:
    data = json.loads(raw.read_text())
    cpu = data["machine_info"].get("cpu", {})
    lines = ["# Large records", "",
             f"Made by `{COMMAND}`: whole `magbench` processes on generated smooth-tumble files (t, bx, by, bz, "
             f"f_ref, temp), one round each, on {cpu.get('brand_raw', '?')} ({cpu.get('count', '?')} cores), "
             f"{data['datetime'][:19]} UTC. Peak memory is the process's maximum resident set.", "",
             "| command | rows | wall s | peak MiB | exit | target | met |", "|---|---|---|---|---|---|---|"]
    for b in data["benchmarks"]:
        info = b["extra_info"]
        command = "calibrate --method lsq" if "calibrate" in b["name"] else "diagnose"
        key = ("calibrate" if "calibrate" in b["name"] else "diagnose", info["rows"])
        target = TARGETS.get(key)
        if target:
            seconds, mib = target
            met = info["wall_s"] <= seconds and (mib is None or info["peak_rss_mib"] <= mib)
            goal = f"<= {seconds:g} s" + (f", <= {mib:g} MiB" if mib else "")
            verdict = "yes" if met else "no"
        else:
            goal, verdict = "baseline (linear growth)", "-"
        lines.append(f"| {command} | {info['rows']:,} | {info['wall_s']:.1f} | {info['peak_rss_mib']:.0f} | "
                     f"{info['code']} | {goal} | {verdict} |")
    text = "\n".join(lines) + "\n"
    out.write_text(text)
    return text


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog=COMMAND)
    p.add_argument("--out", default="results", help="output directory (default: results)")
    out_dir = Path(p.parse_args(argv).out)
    print(report(run(out_dir), out_dir / "large_inputs.md"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
