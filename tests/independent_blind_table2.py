"""The second independent blind check of the diagnosis: ``python -P tests/independent_blind_table2.py --cases 96
--out results/diagnosis/independent_blind2.md`` diagnoses records from tests/independent_forward2.py (a second
forward model, sharing no code with magbench nor physics with tests/independent_forward.py, never used for
tuning) and writes the table, wrong names first, and every verdict.  A copy of independent_blind_table.py with
the generator switched."""
from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from independent_forward2 import make_case  # noqa: E402
from independent_scoring import score  # noqa: E402

from magbench.benchmarks.diagnosis import diagnose  # noqa: E402
from magbench.errors import InputError  # noqa: E402
from magbench.simulate.dataset import Dataset  # noqa: E402


def verdict_of(index: int, root: int = 2026) -> dict:
    case = make_case(index, root)
    data = Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s, temp_C=case.temp_C)
    t0 = time.perf_counter()
    try:
        verdict = diagnose(data, gravity=case.gravity)["verdict"]
    except InputError as exc:  # a refusal names nothing: scored as insufficient_data, with its reason kept
        verdict, refusal = "insufficient_data", str(exc).splitlines()[0][:120]
    else:
        refusal = ""
    s = score(case, verdict)
    return {"index": index, "category": case.category, "schedule": case.schedule, "present": "+".join(case.present),
            "outside": "+".join(case.outside), "verdict": verdict, "wrong": "; ".join(s.wrong_names),
            "named": s.named_present, "n_present": s.n_present, "score": s.score,
            "refusal": refusal, "seconds": time.perf_counter() - t0}


def run(indices, jobs: int = 1, root: int = 2026) -> list[dict]:
    if jobs <= 1:
        return [verdict_of(i, root) for i in indices]
    with ProcessPoolExecutor(jobs) as pool:
        return list(pool.map(verdict_of, indices, [root] * len(indices)))


def cell(text: str) -> str:
    """Text for a Markdown table cell: a verdict's ``a|b`` escaped, so that it does not split the cell."""
    return (text or "").replace("|", "\\|")


def table(rows: list[dict]) -> str:
    cats = sorted({r["category"] for r in rows})
    lines = ["| category | cases | wrong names | recall of present effects | mean score |", "|---|---|---|---|---|"]
    for c in cats + ["all"]:
        part = [r for r in rows if c == "all" or r["category"] == c]
        wrong = sum(1 for r in part if r["wrong"])
        present = sum(r["n_present"] for r in part)
        named = sum(r["named"] for r in part)
        recall = f"{named}/{present}" if present else "-"
        mean = 100 * sum(r["score"] for r in part) / len(part)
        lines.append(f"| {c} | {len(part)} | {wrong} | {recall} | {mean:.1f} % |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=96)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--split", type=str, default="",
                    help="case indices where a new part begins (see the labels below)")
    args = ap.parse_args()
    rows = run(range(args.start, args.start + args.cases), args.jobs)
    text = ["# Second independent blind check of the diagnosis (held out)", "",
            f"{len(rows)} records from `tests/independent_forward2.py` (cases {args.start}-{args.start + args.cases - 1}, "
            "root seed 2026): a second forward model written from the physics, sharing no code with `simulate/`, the "
            "diagnosis or the first independent generator, with its own schedules, sampling, noise and effect "
            "parametrisations and its own effects outside the library. It is never used for tuning. Made by "
            f"`python -P tests/independent_blind_table2.py --cases {args.cases} --start {args.start}`.", "",
            "A wrong name is an effect named that is not in the record (the headline: a user acts on it).", "",
            "No case of this generator has been developed on: every row is held out.", "",
            "## All cases", "", table(rows), ""]
    cuts = [args.start] + [int(c) for c in args.split.split(",") if c] + [args.start + args.cases]
    labels = ["held out (never developed on)"] * (len(cuts) - 1)
    for (a, b), label in zip(zip(cuts[:-1], cuts[1:]), labels):
        part = [r for r in rows if a <= r["index"] < b]
        if part:
            text += [f"## Cases {a}-{b - 1}: {label}", "", table(part), ""]
    text += ["## Every verdict", "", "| case | category | schedule | present | outside | verdict | wrong | score |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        text.append(f"| {r['index']} | {r['category']} | {r['schedule']} | {r['present'] or '-'} | {r['outside'] or '-'} "
                    f"| `{cell(r['verdict'])}` | {cell(r['wrong'])} | {r['score']:g} |")
    out = "\n".join(text) + "\n"
    if args.out:
        args.out.write_text(out, encoding="utf-8")
    print(table(rows))


if __name__ == "__main__":
    main()
