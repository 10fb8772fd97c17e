"""Campaigns: scenarios x calibrators x trials, each run one flat row (nevergrad's benchmark rows).

Seeds follow identity, never list position (COCO): a trial's data and validation-data seeds come from
(root seed, scenario name, trial index), shared by every calibrator of that trial so that they are
compared on the same data, and a calibrator's own seed from (root seed, scenario name, trial index,
configuration label) (``identity_seed``).  Reordering or adding scenarios or methods changes no other run,
so a campaign can grow (``--resume`` with added methods runs only those), and the table does not depend
on the order or the machine the runs are executed on (serially, ``--jobs N`` local processes, or a Dask
cluster).

Durability: every finished run is appended, as it completes, to ``runs.partial.jsonl`` in the output
folder (a header line with the campaign's definition, then one JSON line per run keyed by (scenario,
configuration, trial), its traces and fields included).  Ctrl-C (or SIGTERM) cancels the pending work,
terminates the local worker processes without waiting for the running ones, and writes the tables of
what finished with ``"complete": false`` in the manifest; ``resume=True`` runs only the missing runs and
gives the same tables as an uninterrupted campaign.  The rows of the tables always come from the
checkpoint's JSON, so a resumed campaign and an uninterrupted one are built from identical values.
Local workers exit on their own when the campaign process dies (a watchdog thread polls their parent).
A fresh campaign of ``compare --jobs N`` starts them first (``start_workers``): this module and the ones
it imports at module level load neither pandas nor matplotlib, so the workers are forked from a lean
process and warm up while the campaign process imports what its tables and figures need.

Integrity: one campaign at a time per folder (``campaign_lock``: ``fcntl.flock`` on ``.magbench.lock`` in
it, the holder's pid, host and command written there; a second campaign is refused naming the holder, and
a lock left by a dead process is free again, since the kernel releases it).  Every checkpoint line
carries the sha256 of its content and of the campaign's definition (``line_checksum``): a line edited by
hand, or copied from another campaign, fails it and its run is run again, with a warning.
"""
from __future__ import annotations

import contextlib
import gc
import hashlib
import json
import os
import platform
import signal
import socket
import subprocess
import sys
import threading
import time
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from magbench.benchmarks.metrics import budget_violation, crb_row, run_metrics
from magbench.benchmarks.progress import progress_bar
from magbench.benchmarks.tables import write_tables
from magbench.calibrators import available, make, prefer_compiled_kernels
from magbench.calibrators.methods._gakernel import NOTICE_ENV, announce_compiles
from magbench.errors import InputError
from magbench.simulate.scenarios import get_scenario

if TYPE_CHECKING:  # pandas is imported where the tables are made: a worker process does without it
    import pandas as pd

RUNTIME_COLUMNS = ("runtime_s", "median_runtime_s")
TRACE_POINTS = 100  # convergence traces (kept for every trial) are thinned to at most this many points per run
CHECKPOINT = "runs.partial.jsonl"  # one header line, then one JSON line per finished run
CHECKPOINT_VERSION = 2  # 2: every run line carries a checksum
LOCK = ".magbench.lock"  # in the campaign folder while a campaign runs there
TABLE_FILES = ("runs.csv", "summary.csv", "summary.md", "summary.tex", "traces.csv", "fields.csv", "manifest.json")
CHUNK_MAX = 4  # runs per unit of work sent to a worker: an interrupt loses at most this many per worker
WATCHDOG_S = 0.5  # how often a local worker checks that the campaign process is still alive


class CampaignInterrupted(KeyboardInterrupt):
    """A campaign stopped by SIGINT/SIGTERM after writing the tables of the finished runs."""

    def __init__(self, out: Path, n_done: int, n_total: int, signum: int = signal.SIGINT):
        super().__init__(f"{n_done} of {n_total} runs finished")
        self.out, self.n_done, self.n_total, self.signum = Path(out), n_done, n_total, signum
        self.n_missing = n_total - n_done
        self.exit_status = 128 + int(signum)


class _Terminated(KeyboardInterrupt):
    """SIGTERM received while a campaign runs (handled as Ctrl-C)."""

    signum = signal.SIGTERM


@dataclass(frozen=True)
class MethodSpec:
    """A calibrator name and hyper-parameters; ``label`` is its configuration name in the tables."""

    name: str
    params: tuple = ()

    @property
    def label(self) -> str:
        return self.name + "".join(f" {k}={v}" for k, v in self.params)

    @classmethod
    def parse(cls, text: str) -> MethodSpec:
        """``name`` or ``name:key=value:key=value`` (values parsed as JSON where they can be)."""
        name, *items = text.split(":")
        params: list[tuple[str, object]] = []
        for item in items:
            if "=" not in item or not item.split("=", 1)[0].strip():
                raise InputError(f"method {text!r}: parameter {item!r} is not key=value")
            k, v = item.split("=", 1)
            if k.strip() in OWN_SETTINGS:
                raise InputError(f"method {text!r}: {k.strip()} is not a method's parameter in a campaign: "
                                 f"{OWN_SETTINGS[k.strip()]}")
            if any(k.strip() == seen.strip() for seen, _ in params):  # the last had silently won, under both labels
                raise InputError(f"method {text!r}: {k.strip()} is given twice: give each parameter once")
            with suppress(json.JSONDecodeError):
                v = json.loads(v)
            params.append((k, v))
        return cls(name.strip(), tuple(params))


OWN_SETTINGS = {"seed": "each run's seed comes from --seed and the run's identity (scenario, trial, configuration)",
                "model": "each scenario fixes the model its runs estimate"}
"""Constructor arguments a campaign sets itself, never from a ``name:key=value`` specification."""


def _name_key(name: str) -> int:
    """A stable 64-bit integer for a name (sha256, not Python's salted ``hash``)."""
    return int.from_bytes(hashlib.sha256(name.encode("utf-8")).digest()[:8], "little")


def identity_seed(root: int, scenario: str, trial: int, configuration: str | None = None) -> np.random.SeedSequence:
    """The seed of one run from its identity, never from list positions (COCO seeds an instance from the
    function and instance numbers): the data of (root, scenario, trial), and a calibrator's own seed from
    (root, scenario, trial, configuration label).  Reordering or adding scenarios or methods leaves every
    other run's numbers unchanged."""
    key = [_name_key(scenario), int(trial)] + ([] if configuration is None else [_name_key(configuration)])
    return np.random.SeedSequence(int(root), spawn_key=tuple(key))


MAX_RUNS = 1_000_000
"""The most runs a campaign may have (scenarios x methods x trials): a million runs take about 0.7 GB of task
descriptions and a few minutes to seed before the first runs; more is refused (exit 2)."""


@dataclass(frozen=True)
class Campaign:
    scenarios: tuple[str, ...]
    methods: tuple[MethodSpec, ...]
    trials: int = 10
    seed: int = 0
    traces: bool = True  # keep every trial's convergence trace (thinned) and trial 0's field-vs-heading curves

    def definition(self) -> dict:
        """What identifies the campaign (a resume must match it); JSON-ready."""
        return {"scenarios": list(self.scenarios), "configurations": [m.label for m in self.methods],
                "trials": int(self.trials), "seed": int(self.seed), "traces": bool(self.traces)}

    def tasks(self) -> tuple[list[dict], list[dict]]:
        """All runs as picklable dicts, and the (scenario, method) pairs skipped as not applicable."""

        n_runs = len(self.scenarios) * len(self.methods) * int(self.trials)
        if n_runs < 1:  # no scenario, no method or no trial: a 'complete' campaign of nothing
            raise InputError(f"a campaign needs at least one scenario, one method and one trial (it has "
                             f"{len(self.scenarios)}, {len(self.methods)} and {int(self.trials)})")
        if n_runs > MAX_RUNS:  # a typed zero too many: refused before hours of seeding and gigabytes of tasks
            raise InputError(f"a campaign of {n_runs:,} runs ({len(self.scenarios)} scenario(s) x {len(self.methods)} "
                             f"method(s) x {int(self.trials):,} trials) is more than the limit of {MAX_RUNS:,} runs")
        cals = available()
        tasks, skipped = [], []
        for kind, names in (("scenario", list(self.scenarios)), ("configuration", [m.label for m in self.methods])):
            twice = sorted({n for n in names if names.count(n) > 1})
            if twice:
                raise InputError(f"{kind} {twice[0]!r} given twice")
        for spec in self.methods:
            if spec.name not in cals:
                raise InputError(f"unknown calibrator {spec.name!r}; known: {', '.join(sorted(cals))}")
        for scenario in self.scenarios:
            model = get_scenario(scenario).model
            for trial in range(self.trials):
                data_seed, val_seed = (int(v) for v in identity_seed(self.seed, scenario, trial).generate_state(2))
                for spec in self.methods:
                    if model not in cals[spec.name].supported_models:
                        if trial == 0:
                            skipped.append({"scenario": scenario, "configuration": spec.label,
                                            "reason": f"{spec.name} does not estimate the {model} model"})
                        continue
                    seed = int(identity_seed(self.seed, scenario, trial, spec.label).generate_state(1)[0])
                    tasks.append({"scenario": scenario, "method": spec.name, "params": dict(spec.params),
                                  "configuration": spec.label, "model": model, "trial": trial,
                                  "data_seed": data_seed, "validation_seed": val_seed, "seed": seed,
                                  "keep_trace": self.traces, "keep_fields": self.traces and trial == 0})
        if not tasks:  # every pair skipped: nothing would run, and the tables of nothing are no campaign
            raise InputError("no method of the campaign applies to its scenarios: "
                             + "; ".join(f"{s['configuration']} on {s['scenario']}: {s['reason']}" for s in skipped[:4])
                             + ("; ..." if len(skipped) > 4 else ""))
        return tasks, skipped


def run_task(task: dict) -> dict:
    """One run: simulate the trial's data and validation data, fit, measure.  Never raises."""

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
        if task.get("keep_fields", task.get("keep_trace") and task["trial"] == 0) and data.heading_deg is not None:
            extra["fields"] = {"heading_deg": data.heading_deg.tolist(), "f_ref_nT": data.f_ref_nT.tolist(),  # type: ignore[assignment]
                               "f_before_nT": np.linalg.norm(data.raw_nT, axis=1).tolist(),
                               "f_after_nT": np.linalg.norm(result.correct(data.raw_nT), axis=1).tolist()}
    except Exception as exc:  # a failed run is a row with its error text
        row["error"] = str(exc) if isinstance(exc, InputError) else f"{type(exc).__name__}: {exc}"
    row["_extra"] = extra
    return row


_WARM: dict[str, tuple[int, float]] = {}
"""Configurations warmed: label -> (process id, seconds of the untimed warm-up run).  A forked worker
inherits the campaign process's entries with its loaded kernels and caches (a numba cache load made
once); it warms a configuration again only when that is cheap (``REWARM_S``): a short run's first touches
of inherited memory are page copies that would otherwise be a visible part of its first timed run.  A
spawned or Dask worker warms itself."""
REWARM_S = 0.25


def warm_up(task: dict) -> None:
    """Before this process's first timed run of a configuration: one untimed run of the same task, so that
    what happens once per process (imports, numba compiles and cache loads, SciPy's first LAPACK calls)
    is paid here and not by a run's ``runtime_s``.  Its seconds wait in ``_UNREPORTED`` for the process's
    first timed run of the configuration to report them; nothing is run when this process has warmed the
    configuration already."""
    key = task["configuration"]
    if key in _WARM:
        pid, seconds = _WARM[key]
        if pid == os.getpid() or seconds >= REWARM_S:
            _WARM[key] = (os.getpid(), seconds)
            return

    prefer_compiled_kernels()  # many fits follow: compiled GA kernels from the first, loaded here, untimed
    t0 = time.perf_counter()
    run_task({**task, "keep_trace": False, "keep_fields": False})
    _WARM[key] = (os.getpid(), time.perf_counter() - t0)
    _UNREPORTED[(os.getpid(), key)] = _WARM[key][1]
    # what exists now lives as long as the process: out of the collector's sight, so that a collection in a
    # timed run scans only that run's objects (and forked workers share these pages instead of copying them)
    gc.collect()
    gc.freeze()


def _timed(task: dict) -> dict:
    """``run_task`` after ``warm_up``: the row's ``_extra`` says the warm-up's seconds (in the process that
    made it, on its first timed run of the configuration, also when the warm-up was made before, by
    ``_worker_init``) and whether this was the process's first timed run of the configuration."""
    warm_up(task)
    key = (os.getpid(), task["configuration"])
    warm = _UNREPORTED.pop(key, None)
    first = key not in _FIRST_DONE
    _FIRST_DONE.add(key)
    row = run_task(task)
    row["_extra"].update({"warm_up_s": warm} if warm is not None else {})
    row["_extra"]["first_in_process"] = first
    return row


_FIRST_DONE: set[tuple[int, str]] = set()
_UNREPORTED: dict[tuple[int, str], float] = {}
"""(process id, configuration) -> seconds of a warm-up made in that process that no row has reported yet."""


def run_chunk(tasks: list[dict]) -> list[dict]:
    """Runs in a worker (or serially) with one BLAS/OpenMP thread: the workers already take one core
    each, and a multi-threaded BLAS under that load makes single fits 2-5x slower (threadpoolctl, as
    scikit-learn does).  The limit is lifted again when the chunk ends.  Each configuration is warmed
    (``warm_up``) before its first timed run in the process."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return [_timed(t) for t in tasks]


def task_key(item: dict) -> tuple:
    """A run's stable identity in a campaign (a task or its row)."""
    return (item["scenario"], item["configuration"], int(item["trial"]))


def _chunks(items: list, n: int) -> list[list]:
    size = max(1, min(CHUNK_MAX, len(items) // max(1, 4 * n)))
    return [items[i:i + size] for i in range(0, len(items), size)]


def _worker_init(parent_pid: int, quiet_compiles: bool = False, warm: tuple = ()) -> None:
    """In a local worker: Ctrl-C is the campaign process's business (it terminates us), SIGTERM kills,
    and a daemon thread ends the worker as soon as the campaign process is gone (even by SIGKILL);
    ``quiet_compiles``: the campaign process announced the GA kernels' compiles already; ``warm``: tasks
    whose configurations are warmed (``warm_up``) now, before any chunk arrives (``start_workers``)."""
    if quiet_compiles:
        os.environ[NOTICE_ENV] = "given"
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    ppid = os.getppid()  # the campaign process, or the fork server that exits with it
    if ppid == 1 or (ppid != parent_pid and not _alive(parent_pid)):
        os._exit(1)

    def watch():
        while True:
            time.sleep(WATCHDOG_S)
            if os.getppid() != ppid:
                os._exit(1)

    threading.Thread(target=watch, name="magbench-parent-watchdog", daemon=True).start()
    if warm:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1):  # as in run_chunk
            for task in warm:
                warm_up(task)


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()[0] not in (b"Z", b"X")
    except OSError:
        try:
            os.kill(pid, 0)
            return True
        except ProcessLookupError:
            return False
        except OSError:
            return True


@contextmanager
def _sigterm_as_interrupt():
    """While a campaign runs in the main thread, SIGTERM stops it like Ctrl-C (the finished runs kept)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise _Terminated()

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old if old is not None else signal.SIG_DFL)


def _stop_pool(pool) -> None:
    """Cancel what has not started and terminate the workers now, without waiting for running chunks."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for p in procs:
        with suppress(OSError, AttributeError, ValueError):
            p.terminate()
    pool.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + 3.0
    for p in procs:
        try:
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()
                p.join(1.0)
        except (OSError, AttributeError, ValueError, AssertionError):
            pass


def _new_pool(tasks: list[dict], jobs: int, warm: tuple = ()):
    from concurrent.futures import ProcessPoolExecutor

    quiet = announce_compiles({t["method"] for t in tasks})  # once here, not once per worker
    return ProcessPoolExecutor(max_workers=jobs, initializer=_worker_init, initargs=(os.getpid(), quiet, warm))


EARLY_WARM_MIN = 2
"""``start_workers`` warms a configuration in every worker when it has at least this many runs per worker
(fewer may leave a worker without a run of it: a warm-up for nothing)."""


def start_workers(campaign: Campaign, jobs: int):
    """The local worker processes of a fresh campaign (``run_campaign(..., pool=)``), started now: forked
    from this process before it imports pandas and matplotlib for the tables and figures, each warms the
    campaign's configurations (``_worker_init``) while this process imports, so that the imports fill
    the cores the workers leave idle.  The timed runs start when ``run_campaign`` sends them.  The caller
    stops the pool (``stop_workers``) when the campaign does not reach ``execute``."""
    tasks, _ = campaign.tasks()
    first: dict[str, dict] = {}
    count: dict[str, int] = {}
    for t in tasks:
        first.setdefault(t["configuration"], t)
        count[t["configuration"]] = count.get(t["configuration"], 0) + 1
    # warmed in the reverse order of their first runs: the configuration a worker times first is the one it
    # warmed last, its caches not yet displaced by the others' warm-ups (lsq's first run after ga's warm-up
    # was 1.5x its median; a 0.1 s GA run does not notice the 0.4 ms)
    warm = tuple(reversed([t for label, t in first.items() if count[label] >= EARLY_WARM_MIN * jobs]))
    pool = _new_pool(tasks, jobs, warm)
    pool.submit(os.getpid)  # forks the workers now (a fork pool starts them on its first task)
    return pool


def stop_workers(pool) -> None:
    """Stop a pool from ``start_workers`` (nothing left to do once a campaign has shut it down)."""
    if pool is not None:
        _stop_pool(pool)


def _run_pool(tasks: list[dict], jobs: int, finish, pool=None) -> None:
    from concurrent.futures import as_completed

    pool = pool if pool is not None else _new_pool(tasks, jobs)
    try:
        futures = {pool.submit(run_chunk, [tasks[i] for i in idx]): idx
                   for idx in _chunks(list(range(len(tasks))), jobs)}
        for fut in as_completed(futures):
            finish(futures[fut], fut.result())
    except BaseException:
        _stop_pool(pool)
        raise
    pool.shutdown(wait=True)


DASK_CONNECT_S = 20
"""How long a campaign waits for ``--dask ADDRESS``'s scheduler before it gives up (exit 2)."""


def connect_dask(address: str):
    """A ``distributed.Client`` of the scheduler at ``address``, or an ``InputError`` (one line) when it cannot be
    reached within ``DASK_CONNECT_S``.  ``run_campaign`` connects before it writes anything: an unreachable
    scheduler had left a checkpoint of no runs behind, which a rerun without --resume then refused."""
    from distributed import Client

    try:
        return Client(address, timeout=f"{DASK_CONNECT_S}s")
    except (OSError, TimeoutError, ValueError) as exc:  # distributed says "Timed out trying to connect to ..."
        raise InputError(f"cannot reach the Dask scheduler at {address} within {DASK_CONNECT_S} s "
                         f"({type(exc).__name__}: {str(exc).splitlines()[0][:160] if str(exc) else 'no reason given'}); "
                         "nothing was run or written") from None


def _run_dask(tasks: list[dict], address, finish) -> None:
    """The tasks on the Dask scheduler at ``address``, or on ``address`` itself when it is a connected client
    (``connect_dask``'s), which is closed at the end either way."""
    from distributed import as_completed

    client = connect_dask(address) if isinstance(address, str) else address
    try:
        chunks = _chunks(list(range(len(tasks))), 8)
        futures = client.map(run_chunk, [[tasks[i] for i in idx] for idx in chunks], pure=False)
        index = {f.key: idx for f, idx in zip(futures, chunks)}
        try:
            for fut in as_completed(futures):
                finish(index[fut.key], fut.result())
        except BaseException:
            with contextlib.suppress(Exception):  # the cluster may be gone; nothing more to cancel then
                client.cancel(futures, force=True)
            raise
    finally:
        with suppress(Exception):
            client.close(timeout=5)


def execute(tasks: list[dict], jobs: int = 1, dask_address=None, progress: bool = True,
            on_row=None, n_done: int = 0, pool=None) -> list[dict]:
    """Run the tasks serially, on ``jobs`` local processes, or on a Dask cluster; rows in task order.

    ``on_row(task, row)`` is called in this process as each run finishes (its return value, when not
    None, replaces the row); ``n_done`` runs done earlier start the progress bar.  Every configuration is
    warmed (``warm_up``) before its first timed run in each process, the workers in parallel.  On Ctrl-C
    or SIGTERM the pending work is cancelled, local workers terminated, and ``KeyboardInterrupt``
    re-raised.  ``pool``: local workers started already (``start_workers``), used when ``jobs`` > 1.
    ``dask_address``: a Dask scheduler's address, or a client connected to one (``connect_dask``; closed at the
    end)."""
    bar = progress_bar(n_done + len(tasks), "runs", "run", enabled=progress, initial=n_done, leave=True)
    results: list[dict | None] = [None] * len(tasks)

    def finish(indices, rows):
        for i, row in zip(indices, rows):
            if on_row is not None:
                row = on_row(tasks[i], row) or row
            results[i] = row
        bar.update(len(rows))

    try:
        with _sigterm_as_interrupt():
            if not tasks:
                pass
            elif dask_address is not None:  # an address, or a client connected already (``connect_dask``)
                _run_dask(tasks, dask_address, finish)
            elif jobs > 1:
                _run_pool(tasks, jobs, finish, pool)
            else:
                from threadpoolctl import threadpool_limits

                with threadpool_limits(limits=1):  # as in a worker: runtimes comparable across --jobs
                    for i, task in enumerate(tasks):
                        finish([i], [_timed(task)])
    finally:
        bar.close()
    return results  # type: ignore[return-value]


# ------------------------------------------------------------------------------------ checkpoint
def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.integer, np.floating, np.bool_)):
        return o.item()
    return str(o)


def campaign_digest(definition: dict) -> str:
    """The sha256 of a campaign's definition (canonical JSON): what a checkpoint line's checksum binds it to."""
    return hashlib.sha256(json.dumps(definition, sort_keys=True, default=_json_default).encode("utf-8")).hexdigest()


def line_checksum(campaign_id: str, key: list, row: dict) -> str:
    """sha256 of the campaign's digest and the line's key and row (canonical JSON)."""
    text = json.dumps({"campaign": campaign_id, "key": key, "row": row}, sort_keys=True, default=_json_default)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


class CheckpointCorrupt(InputError):
    """The checkpoint's header line is not a magbench checkpoint header."""


class Checkpoint:
    """``runs.partial.jsonl``: a header with the campaign's definition, then one line per finished run.

    Each line is written with one unbuffered ``write`` as its run comes back, so a run the campaign
    process has received is on disk even if that process is killed the next instant; a torn last line
    (a kill in the middle of a write) is dropped when the file is read."""

    def __init__(self, path: Path, header: dict, done: dict | None = None):
        self.path = Path(path)
        self.done = dict(done or {})
        self.campaign_id = campaign_digest(header.get("campaign") or {})
        if done is None:  # a fresh checkpoint: the header, atomically
            tmp = self.path.with_name(self.path.name + ".tmp")
            tmp.write_text(json.dumps(header) + "\n", encoding="utf-8")
            os.replace(tmp, self.path)
        self._file = open(self.path, "ab", buffering=0)  # noqa: SIM115 - held open for the campaign, closed in close()

    @staticmethod
    def read(path: Path) -> tuple[dict | None, dict]:
        """(header, {key: row}) of a checkpoint; a torn last line is cut off the file, and lines that fail
        their checksum are left out (``read_checked`` counts them)."""
        header, done, _ = Checkpoint.read_checked(path)
        return header, done

    @staticmethod
    def read_checked(path: Path) -> tuple[dict | None, dict, int]:
        """(header, {key: row}, number of run lines refused): a run line counts only when its checksum
        matches its content and the header's campaign (version 2; version 1 lines had none)."""
        path = Path(path)
        data = path.read_bytes()
        if data and not data.endswith(b"\n"):  # a kill during a write: drop the torn line
            data = data[:data.rfind(b"\n") + 1]
            with open(path, "r+b") as f:
                f.truncate(len(data))
        header: dict | None = None
        done: dict = {}
        refused, campaign_id, legacy = 0, "", False
        for n, line in enumerate(data.splitlines()):
            try:
                item = json.loads(line)
            except (ValueError, RecursionError):
                refused += n > 0
                continue
            if n == 0:
                header = item if isinstance(item, dict) and isinstance(item.get("campaign"), dict) else None
                if header is None:
                    break
                campaign_id = campaign_digest(header["campaign"])
                legacy = header.get("magbench_checkpoint") == 1
            elif (isinstance(item, dict) and isinstance(item.get("key"), list) and len(item["key"]) == 3
                  and isinstance(item.get("row"), dict)
                  and (legacy or item.get("sha256") == line_checksum(campaign_id, item["key"], item["row"]))):
                try:
                    done.setdefault(tuple(item["key"]), item["row"])
                except TypeError:  # an unhashable key
                    refused += 1
            else:
                refused += 1
        return header, done, refused

    def add(self, task: dict, row: dict) -> dict:
        """Append a finished run; return the row as it is stored (the JSON round trip)."""
        key = list(task_key(task))
        stored = json.loads(json.dumps(row, default=_json_default))  # the row as JSON gives it back
        line = json.dumps({"key": key, "row": stored, "sha256": line_checksum(self.campaign_id, key, stored)},
                          default=_json_default) + "\n"
        self._file.write(line.encode("utf-8"))
        self.done[task_key(task)] = stored
        return stored

    def close(self) -> None:
        if not self._file.closed:
            with suppress(OSError):
                os.fsync(self._file.fileno())
            self._file.close()


def stored_manifest(out: Path) -> dict | None:
    """``out``'s manifest.json as a JSON object; None when it holds none (not UTF-8, not JSON, a list or a number:
    damaged).  A file that cannot be read raises its ``OSError``; a missing one its ``FileNotFoundError``."""
    try:
        man = json.loads((Path(out) / "manifest.json").read_text(encoding="utf-8"))
    except ValueError:
        return None
    return man if isinstance(man, dict) else None


def stored_definition(out: Path) -> tuple[dict | None, str]:
    """The definition of the campaign held in ``out`` (checkpoint header, else manifest) and its source."""
    out = Path(out)
    if (out / CHECKPOINT).is_file():
        header, _ = Checkpoint.read(out / CHECKPOINT)
        if header is not None:
            return header["campaign"], CHECKPOINT
        raise CheckpointCorrupt(f"cannot resume: the first line of {out / CHECKPOINT} is not a magbench checkpoint "
                                "header (the file is corrupt or not ours); use --force to start over")
    if (out / "manifest.json").is_file():
        man = stored_manifest(out)
        if man is None:  # damaged: no campaign (a list's ``"campaign" in 5`` had been a TypeError)
            return None, "manifest.json"
        if "campaign" in man:
            return man["campaign"], "manifest.json"
        if {"scenarios", "trials", "root_seed", "configurations"} <= set(man):  # written before checkpoints
            return {"scenarios": man["scenarios"], "configurations": list(man["configurations"]),
                    "trials": man["trials"], "seed": man["root_seed"]}, "manifest.json"
    return None, ""


def grows(stored: dict, campaign: Campaign) -> bool:
    """Whether ``campaign`` is the stored one with scenarios or configurations added (same trials, root seed
    and traces): with seeds from identity its runs are the stored runs plus new ones."""
    here = campaign.definition()
    same = all(json.loads(json.dumps(stored.get(k))) == here[k] for k in ("trials", "seed", "traces"))
    return (same and set(stored.get("scenarios", ())) <= set(here["scenarios"])
            and set(stored.get("configurations", ())) <= set(here["configurations"]) and stored != here)


def _check_same_campaign(stored: dict, campaign: Campaign, out: Path, source: str) -> None:
    here = campaign.definition()
    names = {"scenarios": "--scenarios", "configurations": "--methods", "trials": "--trials", "seed": "--seed",
             "traces": "traces"}
    diff = [f"{names.get(k, k)} {stored[k]} there, {here[k]} here" for k in here
            if k in stored and json.loads(json.dumps(stored[k])) != json.loads(json.dumps(here[k]))]
    if diff:
        raise InputError(f"cannot resume: {out} holds another campaign ({'; '.join(diff)}, from its {source}); "
                         "repeat its arguments, or use --force to start over")


def _lock_info(path: Path) -> str:
    try:
        info = json.loads(path.read_text(encoding="utf-8") or "{}")
    except (OSError, ValueError):
        return "another process"
    return (f"process {info.get('pid', '?')} on {info.get('host', '?')}"
            + (f" ({info['command']})" if info.get("command") else ""))


def lock_holder(out) -> str | None:
    """Who holds the campaign lock of ``out`` (None when no one does)."""
    import fcntl

    path = Path(out) / LOCK
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return _lock_info(path)
    except OSError:
        return None
    finally:
        os.close(fd)
    return None


@contextmanager
def campaign_lock(out, command: str = ""):
    """Hold the campaign lock of ``out`` (created if needed) for the block: ``fcntl.flock`` on ``out/LOCK``,
    with this process's pid, host and command written in it.  ``InputError`` naming the holder when
    another process has it; a lock left by a dead process is taken over (the kernel released it).  The
    lock file is removed when the block ends."""
    import fcntl

    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create {out}: {exc.strerror or exc}") from None
    path = out / LOCK
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise InputError(f"cannot lock {out}: {exc.strerror or exc}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise InputError(f"{out} is in use by another campaign ({_lock_info(path)}); wait for it to end, "
                             "or use another --out") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except OSError:
            same = False
        if same:  # not a file its previous holder removed meanwhile
            break
        os.close(fd)
    try:
        info = json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "command": command,
                           "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}) + "\n"
        os.ftruncate(fd, 0)
        os.write(fd, info.encode("utf-8"))
        yield path
    finally:
        with suppress(OSError):
            path.unlink()
        os.close(fd)


COMPARISON_FILES = ("ert.csv", "ecdf.csv", "anytime.csv", "profile.csv", "paired_tests.csv", "win_rate.csv")
"""What ``benchmarks.comparison.write_comparison`` writes in ``comparison/``."""


def clear_outputs(out) -> list[Path]:
    """Remove what a campaign writes in ``out`` (tables, manifest, checkpoint, figures, report.html) and
    nothing else: figures/ loses only its .png/.svg files, and goes only if that leaves it empty."""
    out = Path(out)
    removed = []
    for name in (*TABLE_FILES, CHECKPOINT, CHECKPOINT + ".tmp", "report.html", "comparison.md"):
        path = out / name
        if path.is_file() or path.is_symlink():
            path.unlink()
            removed.append(path)
    comparison = out / "comparison"
    if comparison.is_dir() and not comparison.is_symlink():
        for name in COMPARISON_FILES:
            if (comparison / name).is_file():
                (comparison / name).unlink()
                removed.append(comparison / name)
        with contextlib.suppress(OSError):  # something else lives there: not ours to delete
            comparison.rmdir()
    figures = out / "figures"
    if figures.is_symlink():
        figures.unlink()
        removed.append(figures)
    elif figures.is_dir():
        for path in sorted(figures.iterdir()):
            if path.suffix in (".png", ".svg", ".pdf") and (path.is_file() or path.is_symlink()):
                path.unlink()
                removed.append(path)
        with contextlib.suppress(OSError):  # something else lives there: not ours to delete
            figures.rmdir()
    return removed


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

    versions = {}
    for pkg in ("magbench", "numpy", "scipy", "nlopt", "pandas", "matplotlib", "ppigrf", "dask", "distributed"):
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None  # type: ignore[assignment]
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
                 command: str = "", progress: bool = True, resume: bool = False, pool=None) -> pd.DataFrame:
    """Run a campaign and write runs.csv, summary.{csv,md,tex}, traces.csv, fields.csv, manifest.json.

    Finished runs go to the checkpoint as they complete.  ``resume=True`` continues the campaign held in
    ``out_dir`` (InputError if it is another campaign), running only the missing runs.  On Ctrl-C or
    SIGTERM the tables of the finished runs are written (manifest ``"complete": false``) and
    ``CampaignInterrupted`` is raised.  The returned frame's ``attrs`` say ``n_new`` (runs done by this
    call), ``n_resumed`` (taken from the checkpoint) and ``already_complete`` (a resume with nothing to
    do: then nothing is rewritten).  ``pool``: the local workers, started already (``start_workers``)."""
    out = Path(out_dir)
    tasks, skipped = campaign.tasks()
    ckpt_path = out / CHECKPOINT
    done: dict | None = None
    growing = False
    if resume:
        stored, source = stored_definition(out)
        growing = stored is not None and source == CHECKPOINT and grows(stored, campaign)
        if stored is not None and not growing:
            _check_same_campaign(stored, campaign, out, source)
        if source == CHECKPOINT:
            keys = {task_key(t) for t in tasks}
            _, on_file, refused = Checkpoint.read_checked(ckpt_path)
            done = {k: v for k, v in on_file.items() if k in keys}
            if refused:
                sys.stderr.write(f"magbench: warning: {refused} line(s) of {ckpt_path} failed their checksum "
                                 "(edited, corrupt, or from another campaign): those runs are run again\n")
            elif not growing and len(done) == len(tasks):
                finished = _complete_tables(out)
                if finished is not None:
                    return finished
        elif stored is not None:
            runs_done = _complete_tables(out)
            if runs_done is not None:
                return runs_done
            damaged = runs_table_problem(out / "runs.csv") if (out / "runs.csv").is_file() else None
            raise InputError(f"cannot resume: {damaged}, and no {CHECKPOINT} to rebuild it from; use --force to start "
                             "over" if damaged else f"cannot resume: {out} has no {CHECKPOINT} holding its finished runs; "
                             "use --force to start over")
        elif out.is_dir() and any(out.iterdir()):
            raise InputError(f"cannot resume: {out} holds no campaign (no readable {CHECKPOINT} or manifest.json)")
    todo = [t for t in tasks if task_key(t) not in (done or {})]  # the checkpoint below holds ``done``'s runs
    # the scheduler is reached before anything is written (an unreachable one had left a checkpoint of no runs behind)
    client = connect_dask(dask_address) if dask_address and todo else None
    try:
        out.mkdir(parents=True, exist_ok=True)
        header = {"magbench_checkpoint": CHECKPOINT_VERSION, "campaign": campaign.definition(), "command": command}
        if growing:  # the stored runs, signed again under the grown campaign's definition
            checkpoint = Checkpoint(ckpt_path, header)
            by_key = {task_key(t): t for t in tasks}
            for key, row in (done or {}).items():
                checkpoint.add(by_key[key], row)
        else:
            checkpoint = Checkpoint(ckpt_path, header, done)
    except BaseException:
        if client is not None:
            with suppress(Exception):
                client.close(timeout=5)
        raise
    n_resumed = len(tasks) - len(todo)
    t0 = time.perf_counter()
    interrupted = None
    try:
        execute(todo, jobs=jobs, dask_address=client, progress=progress, on_row=checkpoint.add,
                n_done=n_resumed, pool=pool)
    except KeyboardInterrupt as exc:
        interrupted = exc
    finally:
        checkpoint.close()
    wall = time.perf_counter() - t0
    on_disk = Checkpoint.read(ckpt_path)[1]  # what an interrupt may not have let reach checkpoint.done is there
    rows = [on_disk[task_key(t)] for t in tasks if task_key(t) in on_disk]
    n_missing = len(tasks) - len(rows)
    runs = _write_campaign_tables(campaign, out, rows, skipped, command, wall, jobs, dask_address, n_missing)
    runs.attrs.update(n_new=len(rows) - n_resumed, n_resumed=n_resumed, already_complete=False,
                      n_missing=n_missing)
    # the checkpoint stays: it is the campaign's exact record, from which ``--resume`` with added scenarios
    # or methods grows it (the tables round their numbers)
    if interrupted is not None:
        raise CampaignInterrupted(out, len(rows), len(tasks), getattr(interrupted, "signum", signal.SIGINT)) \
            from interrupted
    return runs


RUNS_KEY_COLUMNS = ("scenario", "configuration", "trial")


def runs_table_problem(path: Path) -> str | None:
    """Why a campaign's runs.csv cannot be reported on (unreadable, a key column missing, or rows without a
    scenario, a configuration or an integer trial: a damaged or hand-edited table), or None."""
    import pandas as pd

    try:
        runs = pd.read_csv(path, dtype={"configuration": str, "scenario": str}, keep_default_na=False,
                           na_values={"trial": [""]})
    except (OSError, UnicodeDecodeError, pd.errors.EmptyDataError, pd.errors.ParserError) as exc:
        return f"{path} is not a readable runs table ({str(exc).splitlines()[0][:120]})"
    missing = [c for c in RUNS_KEY_COLUMNS if c not in runs.columns]
    if missing:
        return f"{path} has no {', '.join(missing)} column: not a campaign's runs table"
    trial = pd.to_numeric(runs["trial"], errors="coerce")
    bad = (runs["scenario"].str.strip() == "") | (runs["configuration"].str.strip() == "") | ~np.isfinite(trial) | \
        (trial != trial.round())
    if bad.any():
        lines = (np.flatnonzero(bad.to_numpy()) + 2).tolist()
        where = ", ".join(map(str, lines[:5])) + (f" and {len(lines) - 5} more" if len(lines) > 5 else "")
        return f"{path}: line {where} has no scenario, configuration or whole trial number (a damaged or edited table)"
    for column in FLAG_COLUMNS:  # the figures' masks read them as booleans (a 2 had been an internal error)
        if column in runs.columns:
            text = runs[column].astype(str).str.strip()
            odd = ~text.isin(("True", "False", ""))
            if odd.any():
                line = int(np.flatnonzero(odd.to_numpy())[0]) + 2
                return (f"{path}: column {column} holds {text[odd].iloc[0][:20]!r} on line {line}, not True or False "
                        "(a damaged or edited table)")
    return None


FLAG_COLUMNS = ("success", "accepted")
"""Columns of runs.csv that hold True or False (``runs_table_problem``)."""


def _complete_tables(out: Path) -> pd.DataFrame | None:
    """runs.csv of a finished campaign (manifest says complete), marked ``already_complete``; else None."""
    try:
        man = stored_manifest(out)
    except OSError:
        return None
    if man is None:  # damaged: not known to be complete (a list had been an AttributeError)
        return None
    if not (man.get("complete", True) and (out / "runs.csv").is_file()) or runs_table_problem(out / "runs.csv"):
        return None  # a damaged runs.csv is not a finished campaign's table: rebuilt from the checkpoint, or refused
    import pandas as pd

    runs = pd.read_csv(out / "runs.csv", keep_default_na=False)
    runs.attrs.update(n_new=0, n_resumed=len(runs), already_complete=True, n_missing=0)
    return runs


def one_time_costs(rows: list[dict]) -> dict:
    """Per configuration: the untimed warm-up runs (seconds, one per process that made one), the median
    timed runtime, the one-time cost (the longest warm-up less that median: imports, compiles, cache
    loads) and the largest ratio of a process's first timed run to the median (1 when warming works)."""
    by: dict[str, dict] = {}
    for row in rows:
        extra = row.get("_extra") or {}
        entry = by.setdefault(row["configuration"], {"warm": [], "runtimes": [], "first": []})
        if extra.get("warm_up_s") is not None:
            entry["warm"].append(float(extra["warm_up_s"]))
        runtime = row.get("runtime_s")
        if isinstance(runtime, (int, float)) and np.isfinite(runtime) and not row.get("error"):
            entry["runtimes"].append(float(runtime))
            if extra.get("first_in_process"):
                entry["first"].append(float(runtime))
    out = {}
    for label, e in by.items():
        median = float(np.median(e["runtimes"])) if e["runtimes"] else float("nan")
        out[label] = {"warm_up_s": [round(w, 4) for w in e["warm"]], "median_runtime_s": round(median, 6),
                      "one_time_s": round(max(e["warm"]) - median, 4) if e["warm"] and np.isfinite(median) else None,
                      "first_run_over_median": round(max(e["first"]) / median, 3)
                      if e["first"] and np.isfinite(median) and median > 0 else None}
    return out


def _write_campaign_tables(campaign: Campaign, out: Path, rows: list[dict], skipped: list[dict], command: str,
                           wall: float, jobs: int, dask_address: str | None, n_missing: int) -> pd.DataFrame:

    import pandas as pd

    traces, fields, flat = [], [], []
    costs = one_time_costs(rows)
    for row in rows:
        row = dict(row)
        extra = row.pop("_extra", {}) or {}
        flat.append(row)
        for ev, best, mean in extra.get("trace", []):
            traces.append({"scenario": row["scenario"], "configuration": row["configuration"],
                           "trial": int(row["trial"]), "evaluations": int(ev), "best_F": best, "mean_F": mean})
        if "fields" in extra:
            f = extra["fields"]
            for i in range(len(f["heading_deg"])):
                fields.append({"scenario": row["scenario"], "configuration": row["configuration"],
                               **{k: v[i] for k, v in f.items()}})
    runs = pd.DataFrame(flat)
    if len(runs):
        order = {s: i for i, s in enumerate(campaign.scenarios)}
        m_order = {m.label: i for i, m in enumerate(campaign.methods)}
        runs = runs.sort_values(by=["scenario", "configuration", "trial"],
                                key=lambda c: c.map(order) if c.name == "scenario" else
                                (c.map(m_order) if c.name == "configuration" else c), kind="stable")
        runs = runs.reset_index(drop=True)
    else:
        runs = pd.DataFrame(columns=["scenario", "method", "configuration", "model", "trial", "seed", "data_seed",
                                     "error"])
    man = manifest(campaign, skipped, command)
    man["campaign"] = campaign.definition()
    man["complete"] = n_missing == 0
    man["n_missing"] = n_missing
    man["wall_time_s"] = round(wall, 3)
    man["jobs"] = jobs
    man["dask"] = bool(dask_address)
    man["n_runs"] = len(runs)
    man["n_failed"] = int((runs["error"] != "").sum()) if len(runs) else 0
    man["one_time_costs"] = costs  # kept out of runtime_s: each configuration warmed once per process
    for name, frame in (("traces.csv", traces), ("fields.csv", fields)):
        if not frame:  # write_tables skips an empty one: do not leave an older file behind
            (out / name).unlink(missing_ok=True)
    write_tables(runs, pd.DataFrame(traces), pd.DataFrame(fields), man, out)
    return runs
