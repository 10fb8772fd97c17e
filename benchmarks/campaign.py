"""Campaigns: scenarios x calibrators x trials, each run one flat row (nevergrad's benchmark rows).

Seeds: one root ``SeedSequence(seed)`` spawns a child per scenario, a grandchild per trial (the data
seed and the validation-data seed, shared by every calibrator of that trial so that they are compared
on the same data) and, under it, one per calibrator configuration (the calibrator's own seed).  Every
(scenario, calibrator, trial) therefore has its own seed, and the table does not depend on the order
or the machine the runs are executed on (serially, ``--jobs N`` local processes, or a Dask cluster).
"""
from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np
import pandas as pd

from magbench.errors import InputError

RUNTIME_COLUMNS = ("runtime_s", "median_runtime_s")
TRACE_POINTS = 200  # convergence traces are thinned to at most this many points per run


@dataclass(frozen=True)
class MethodSpec:
    """A calibrator name and hyper-parameters; ``label`` is its configuration name in the tables."""

    name: str
    params: tuple = ()

    @property
    def label(self) -> str:
        return self.name + "".join(f" {k}={v}" for k, v in self.params)

    @classmethod
    def parse(cls, text: str) -> "MethodSpec":
        """``name`` or ``name:key=value:key=value`` (values parsed as JSON where they can be)."""
        name, *items = text.split(":")
        params = []
        for item in items:
            if "=" not in item:
                raise InputError(f"method {text!r}: parameter {item!r} is not key=value")
            k, v = item.split("=", 1)
            try:
                v = json.loads(v)
            except json.JSONDecodeError:
                pass
            params.append((k, v))
        return cls(name.strip(), tuple(params))


@dataclass(frozen=True)
class Campaign:
    scenarios: tuple[str, ...]
    methods: tuple[MethodSpec, ...]
    trials: int = 10
    seed: int = 0
    traces: bool = True  # keep convergence traces and field-vs-heading curves of trial 0

    def tasks(self) -> tuple[list[dict], list[dict]]:
        """All runs as picklable dicts, and the (scenario, method) pairs skipped as not applicable."""
        from magbench.calibrators import available
        from magbench.simulate.scenarios import get_scenario

        cals = available()
        tasks, skipped = [], []
        for spec in self.methods:
            if spec.name not in cals:
                raise InputError(f"unknown calibrator {spec.name!r}; known: {', '.join(sorted(cals))}")
        root = np.random.SeedSequence(self.seed)
        for s_idx, (scenario, s_seq) in enumerate(zip(self.scenarios, root.spawn(len(self.scenarios)))):
            model = get_scenario(scenario).model
            for trial, t_seq in enumerate(s_seq.spawn(self.trials)):
                data_seed, val_seed = (int(v) for v in t_seq.generate_state(2))
                for m_idx, (spec, m_seq) in enumerate(zip(self.methods, t_seq.spawn(len(self.methods)))):
                    if model not in cals[spec.name].supported_models:
                        if trial == 0:
                            skipped.append({"scenario": scenario, "configuration": spec.label,
                                            "reason": f"{spec.name} does not estimate the {model} model"})
                        continue
                    tasks.append({"scenario": scenario, "method": spec.name, "params": dict(spec.params),
                                  "configuration": spec.label, "model": model, "trial": trial,
                                  "data_seed": data_seed, "validation_seed": val_seed,
                                  "seed": int(m_seq.generate_state(1)[0]),
                                  "keep_trace": self.traces and trial == 0})
        return tasks, skipped


def run_task(task: dict) -> dict:
    """One run: simulate the trial's data and validation data, fit, measure.  Never raises."""
    from magbench.benchmarks.metrics import budget_violation, crb_row, run_metrics
    from magbench.calibrators import make
    from magbench.simulate.scenarios import get_scenario

    row = {k: task[k] for k in ("scenario", "method", "configuration", "model", "trial", "seed", "data_seed")}
    row["error"] = ""
    extra = {}
    try:
        scenario = get_scenario(task["scenario"])
        data = scenario.build(task["data_seed"])
        validation = scenario.build(task["validation_seed"])
        calibrator = make(task["method"], model=task["model"], seed=task["seed"], **task["params"])
        result = calibrator.fit(data)
        row.update(run_metrics(result, data, validation))
        row["error"] = budget_violation(result, calibrator.budget)
        row.update(crb_row(data, task["model"]))
        if task.get("keep_trace"):
            trace = np.asarray(result.trace, dtype=float).reshape(-1, 3)
            if len(trace) > TRACE_POINTS:
                trace = trace[np.unique(np.geomspace(1, len(trace), TRACE_POINTS).astype(int) - 1)]
            extra["trace"] = trace.tolist()
            if data.heading_deg is not None:
                extra["fields"] = {"heading_deg": data.heading_deg.tolist(), "f_ref_nT": data.f_ref_nT.tolist(),
                                   "f_before_nT": np.linalg.norm(data.raw_nT, axis=1).tolist(),
                                   "f_after_nT": np.linalg.norm(result.correct(data.raw_nT), axis=1).tolist()}
    except Exception as exc:  # a failed run is a row with its error text
        row["error"] = str(exc) if isinstance(exc, InputError) else f"{type(exc).__name__}: {exc}"
    row["_extra"] = extra
    return row


def run_chunk(tasks: list[dict]) -> list[dict]:
    return [run_task(t) for t in tasks]


def _chunks(tasks: list[dict], n: int) -> list[list[dict]]:
    size = max(1, min(64, len(tasks) // max(1, 4 * n)))
    return [tasks[i:i + size] for i in range(0, len(tasks), size)]


def execute(tasks: list[dict], jobs: int = 1, dask_address: str | None = None, progress: bool = True) -> list[dict]:
    """Run the tasks serially, on ``jobs`` local processes, or on a Dask cluster; rows in task order."""
    from tqdm import tqdm

    bar = tqdm(total=len(tasks), desc="runs", unit="run", disable=not progress, file=sys.stderr,
               mininterval=0.5, dynamic_ncols=True)
    chunks = _chunks(tasks, jobs if not dask_address else 8)
    results: list[list[dict] | None] = [None] * len(chunks)
    try:
        if dask_address:
            from distributed import Client, as_completed

            with Client(dask_address, timeout="20s") as client:
                futures = client.map(run_chunk, chunks, pure=False)
                index = {f.key: i for i, f in enumerate(futures)}
                for fut in as_completed(futures):
                    results[index[fut.key]] = fut.result()
                    bar.update(len(results[index[fut.key]]))
        elif jobs > 1:
            from concurrent.futures import ProcessPoolExecutor, as_completed as done

            with ProcessPoolExecutor(max_workers=jobs) as pool:
                futures = {pool.submit(run_chunk, c): i for i, c in enumerate(chunks)}
                for fut in done(futures):
                    results[futures[fut]] = fut.result()
                    bar.update(len(results[futures[fut]]))
        else:
            for i, c in enumerate(chunks):
                results[i] = run_chunk(c)
                bar.update(len(c))
    finally:
        bar.close()
    return [row for chunk in results for row in chunk]


def _git_commit() -> str:
    try:
        root = Path(__file__).resolve().parent.parent
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=5)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, timeout=5).stdout.strip()
        return out.stdout.strip() + ("+dirty" if dirty else "") if out.returncode == 0 else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def manifest(campaign: Campaign, skipped: list[dict], command: str) -> dict:
    from magbench.calibrators import make

    versions = {}
    for pkg in ("magbench", "numpy", "scipy", "nlopt", "pandas", "matplotlib", "ppigrf", "dask", "distributed"):
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None
    configs = {}
    for spec in campaign.methods:
        hp = make(spec.name, **dict(spec.params)).get_params()
        configs[spec.label] = {k: (v if isinstance(v, (int, float, str, bool, type(None))) else repr(v))
                               for k, v in hp.items() if k not in ("seed", "model")}
    return {"command": command, "root_seed": campaign.seed, "trials": campaign.trials,
            "scenarios": list(campaign.scenarios), "configurations": configs, "skipped": skipped,
            "seeding": "SeedSequence(root) -> scenario -> trial (data, validation seeds) -> calibrator seed",
            "git_commit": _git_commit(), "versions": versions, "python": platform.python_version(),
            "machine": {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
                        "cpus": os.cpu_count()}}


def run_campaign(campaign: Campaign, out_dir, jobs: int = 1, dask_address: str | None = None,
                 command: str = "", progress: bool = True) -> pd.DataFrame:
    """Run a campaign and write runs.csv, summary.{csv,md,tex}, traces.csv, fields.csv, manifest.json."""
    from magbench.benchmarks.tables import write_tables

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tasks, skipped = campaign.tasks()
    t0 = time.perf_counter()
    rows = execute(tasks, jobs=jobs, dask_address=dask_address, progress=progress)
    wall = time.perf_counter() - t0
    traces, fields = [], []
    for row in rows:
        extra = row.pop("_extra", {})
        for ev, best, mean in extra.get("trace", []):
            traces.append({"scenario": row["scenario"], "configuration": row["configuration"],
                           "evaluations": int(ev), "best_F": best, "mean_F": mean})
        if "fields" in extra:
            f = extra["fields"]
            for i in range(len(f["heading_deg"])):
                fields.append({"scenario": row["scenario"], "configuration": row["configuration"],
                               **{k: v[i] for k, v in f.items()}})
    runs = pd.DataFrame(rows)
    order = {s: i for i, s in enumerate(campaign.scenarios)}
    m_order = {m.label: i for i, m in enumerate(campaign.methods)}
    runs = runs.sort_values(by=["scenario", "configuration", "trial"],
                            key=lambda c: c.map(order) if c.name == "scenario" else
                            (c.map(m_order) if c.name == "configuration" else c), kind="stable")
    runs = runs.reset_index(drop=True)
    man = manifest(campaign, skipped, command)
    man["wall_time_s"] = round(wall, 3)
    man["jobs"] = jobs
    man["dask"] = bool(dask_address)
    man["n_runs"] = len(runs)
    man["n_failed"] = int((runs["error"] != "").sum()) if len(runs) else 0
    write_tables(runs, pd.DataFrame(traces), pd.DataFrame(fields), man, out)
    return runs
