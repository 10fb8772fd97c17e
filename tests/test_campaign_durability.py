"""Campaigns lose nothing: finished runs are checkpointed as they complete, Ctrl-C stops at once and keeps
them, --resume completes the campaign with the tables of an uninterrupted run, killing the campaign
process leaves no worker behind, --force clears only the campaign's own outputs."""
import json
import os
import signal
import subprocess
import sys
import time

import pandas as pd
import pytest

from magbench.benchmarks import campaign as campaign_module
from magbench.benchmarks.campaign import (
    CHECKPOINT,
    RUNTIME_COLUMNS,
    Campaign,
    CampaignInterrupted,
    Checkpoint,
    MethodSpec,
    run_campaign,
)
from magbench.benchmarks.cli import main

# ~0.25 s per ga run: long enough to interrupt, short enough for seconds-long tests
METHODS = ["lsq", "ga:generations=4000"]  # long enough (~0.3 s a run) that an interrupt lands mid-campaign
TRIALS = 12
SEED = 7
N_RUNS = len(METHODS) * TRIALS


def compare_args(out, *extra, trials=TRIALS, seed=SEED):
    return ["compare", "--scenarios", "sphere9", "--methods", *METHODS, "--trials", str(trials), "--seed", str(seed),
            "--out", str(out), "--no-figures", *extra]


def start(args, tmp_path, name):
    """``python -m magbench ARGS`` in the background; stdout/stderr to files (a stray worker holding a pipe
    must not be able to block the test)."""
    stdout = open(tmp_path / f"{name}.out", "w")  # noqa: SIM115 - handed to the child process, closed by the test
    stderr = open(tmp_path / f"{name}.err", "w")  # noqa: SIM115
    # SIGINT back to its default in the child: a test run started in the background by a non-interactive
    # shell inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler at all
    proc = subprocess.Popen([sys.executable, "-P", "-m", "magbench", *args], stdout=stdout, stderr=stderr,
                            stdin=subprocess.DEVNULL, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    stdout.close()
    stderr.close()
    return proc


def checkpoint_lines(out):
    path = out / CHECKPOINT
    return path.read_text().splitlines() if path.is_file() else []


def wait_for_runs(proc, out, n, timeout=120.0):
    """Wait until the checkpoint holds ``n`` finished runs (its first line is the header)."""
    deadline = time.monotonic() + timeout
    while len(checkpoint_lines(out)) < n + 1:
        assert proc.poll() is None, "the campaign ended before it could be interrupted"
        assert time.monotonic() < deadline, "no run was checkpointed"
        time.sleep(0.02)
    return checkpoint_lines(out)


def descendants(pid):
    try:
        import psutil
    except ImportError:  # /proc: children of children
        found, frontier = [], [pid]
        while frontier:
            parent = frontier.pop()
            for entry in os.listdir("/proc"):
                if entry.isdigit():
                    try:
                        with open(f"/proc/{entry}/stat") as f:
                            ppid = int(f.read().rsplit(")", 1)[1].split()[1])
                    except (OSError, IndexError, ValueError):
                        continue
                    if ppid == parent:
                        found.append(int(entry))
                        frontier.append(int(entry))
        return found
    return [p.pid for p in psutil.Process(pid).children(recursive=True)]


def alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except OSError:
        return False


def wait_gone(pids, timeout=10.0):
    deadline = time.monotonic() + timeout
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    return [p for p in pids if alive(p)]


def table(path):
    frame = pd.read_csv(path, keep_default_na=False)
    return frame.drop(columns=[c for c in RUNTIME_COLUMNS if c in frame])


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    out = tmp_path_factory.mktemp("uninterrupted") / "camp"
    assert main(compare_args(out, "--quiet")) == 0
    return out


def test_ctrl_c_keeps_finished_runs_and_resume_gives_the_uninterrupted_tables(uninterrupted, tmp_path):
    out = tmp_path / "camp"
    proc = start(compare_args(out, "--jobs", "2", "--quiet"), tmp_path, "first")
    try:
        before = wait_for_runs(proc, out, 1)
        workers = descendants(proc.pid)
        sent = time.monotonic()
        proc.send_signal(signal.SIGINT)
        status = proc.wait(timeout=60)
        stopped_after = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
    err = (tmp_path / "first.err").read_text()
    assert status == 130, err
    assert stopped_after < 15, stopped_after
    assert not wait_gone(workers), "a worker outlived the interrupted campaign"
    assert (tmp_path / "first.out").read_text() == ""
    message = [line for line in err.splitlines() if line.strip()]
    assert len(message) == 1 and "interrupted" in message[0] and "--resume" in message[0], err
    after = checkpoint_lines(out)
    assert after[:len(before)] == before  # append-only: nothing finished was lost
    n_done = len(after) - 1
    assert 1 <= n_done < N_RUNS
    assert f"{n_done} of {N_RUNS} runs" in message[0]
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] is False and manifest["n_missing"] == N_RUNS - n_done
    assert manifest["n_runs"] == n_done == len(pd.read_csv(out / "runs.csv"))
    assert not (out / "report.html").exists()

    # the same command again is refused (it would start over); --resume completes it, the bar starting at n_done
    assert main(compare_args(out, "--quiet")) == 2
    proc = start(compare_args(out, "--jobs", "2", "--resume"), tmp_path, "resume")
    assert proc.wait(timeout=300) == 0, (tmp_path / "resume.err").read_text()
    assert f"{n_done}/{N_RUNS}" in (tmp_path / "resume.err").read_text()
    assert f"{n_done} from the checkpoint, {N_RUNS - n_done} run now" in (tmp_path / "resume.out").read_text()
    for name in ("runs.csv", "summary.csv", "traces.csv"):
        pd.testing.assert_frame_equal(table(out / name), table(uninterrupted / name))
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] is True and manifest["n_missing"] == 0 and manifest["n_runs"] == N_RUNS
    assert (out / CHECKPOINT).exists()  # kept: the exact record a grown campaign resumes from


def test_killed_campaign_process_leaves_no_worker(tmp_path):
    out = tmp_path / "camp"
    proc = start(compare_args(out, "--jobs", "2", "--quiet", trials=40), tmp_path, "killed")
    try:
        wait_for_runs(proc, out, 1)
        workers = descendants(proc.pid)
        assert workers, "no worker process to watch"
        proc.send_signal(signal.SIGKILL)
        assert proc.wait(timeout=30) == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            proc.kill()
    left = wait_gone(workers)
    for pid in left:  # do not leave them running for the rest of the suite
        os.kill(pid, signal.SIGKILL)
    assert not left, f"workers {left} outlived their campaign process"
    # what finished before the kill is still there to resume
    header, done = Checkpoint.read(out / CHECKPOINT)
    assert header["campaign"]["trials"] == 40 and len(done) >= 1


def test_sigterm_stops_like_ctrl_c(tmp_path):
    out = tmp_path / "camp"
    proc = start(compare_args(out, "--jobs", "2", "--quiet"), tmp_path, "term")
    try:
        wait_for_runs(proc, out, 1)
        workers = descendants(proc.pid)
        proc.send_signal(signal.SIGTERM)
        status = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert status == 128 + signal.SIGTERM, (tmp_path / "term.err").read_text()
    assert not wait_gone(workers)
    assert json.loads((out / "manifest.json").read_text())["complete"] is False


def test_interrupted_serial_campaign_resumes_in_process(uninterrupted, tmp_path, monkeypatch):
    real, calls = campaign_module.run_task, []

    def interrupted_after_five(task):
        calls.append(task)
        if len(calls) == 6:
            raise KeyboardInterrupt
        return real(task)

    camp = Campaign(("sphere9",), tuple(MethodSpec.parse(m) for m in METHODS), trials=TRIALS, seed=SEED)
    monkeypatch.setattr(campaign_module, "run_task", interrupted_after_five)
    with pytest.raises(CampaignInterrupted) as stop:
        run_campaign(camp, tmp_path, progress=False)
    assert (stop.value.n_done, stop.value.n_missing, stop.value.exit_status) == (5, N_RUNS - 5, 130)
    monkeypatch.setattr(campaign_module, "run_task", real)
    runs = run_campaign(camp, tmp_path, progress=False, resume=True)
    assert (runs.attrs["n_resumed"], runs.attrs["n_new"]) == (5, N_RUNS - 5)
    for name in ("runs.csv", "summary.csv", "traces.csv"):
        pd.testing.assert_frame_equal(table(tmp_path / name), table(uninterrupted / name))


def test_torn_last_checkpoint_line_is_dropped(tmp_path):
    camp = Campaign(("sphere9",), (MethodSpec("lsq"),), trials=3, seed=1)
    path = tmp_path / CHECKPOINT
    ck = Checkpoint(path, {"campaign": camp.definition()})
    tasks, _ = camp.tasks()
    for task in tasks[:2]:
        ck.add(task, {"scenario": task["scenario"], "configuration": task["configuration"], "trial": task["trial"]})
    ck.close()
    with open(path, "ab") as f:
        f.write(b'{"key": ["sphere9", "lsq", 2], "row": {"scen')  # killed in the middle of a write
    header, done = Checkpoint.read(path)
    assert header["campaign"] == camp.definition() and sorted(done) == [("sphere9", "lsq", 0), ("sphere9", "lsq", 1)]
    assert path.read_bytes().endswith(b"}\n")


def test_resume_with_other_arguments_is_refused(tmp_path, capsys):
    out = tmp_path / "camp"
    out.mkdir()
    camp = Campaign(("sphere9",), tuple(MethodSpec.parse(m) for m in METHODS), trials=TRIALS, seed=SEED)
    Checkpoint(out / CHECKPOINT, {"campaign": camp.definition()}).close()
    saved = (out / CHECKPOINT).read_bytes()
    for changed in (compare_args(out, "--resume", trials=TRIALS + 1), compare_args(out, "--resume", seed=SEED + 1),
                    [a if a != "lsq" else "ellipsoid" for a in compare_args(out, "--resume")],
                    [a if a != "sphere9" else "cap9" for a in compare_args(out, "--resume")]):
        capsys.readouterr()
        assert main(changed) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "cannot resume" in err, err
        assert (out / CHECKPOINT).read_bytes() == saved and sorted(os.listdir(out)) == [CHECKPOINT]
    assert main(compare_args(out, "--resume", "--force")) == 2  # contradictory


def test_resuming_a_complete_campaign_runs_and_rewrites_nothing(tmp_path, capsys):
    out = tmp_path / "camp"
    assert main(compare_args(out, "--quiet", trials=2)) == 0
    stamps = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    capsys.readouterr()
    assert main(compare_args(out, "--resume", "--json", trials=2)) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["complete"] is True and obj["n_new"] == 0 and obj["n_runs"] == 4
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == stamps
    assert main(compare_args(out, "--resume", "--quiet", trials=2)) == 0
    assert "already complete" in capsys.readouterr().out
    assert main(compare_args(out, "--resume", trials=3)) == 2


def test_force_clears_the_campaign_outputs_and_nothing_else(tmp_path):
    out = tmp_path / "camp"
    (out / "figures").mkdir(parents=True)
    stale = ["figures/errors_lu2014.png", "figures/errors_lu2014.svg", "report.html", "traces.csv", "fields.csv",
             "summary.tex", CHECKPOINT]
    mine = ["notes.txt", "figures/sketch.txt"]
    for name in stale + mine:
        (out / name).write_text("old\n")
    assert main(compare_args(out, "--quiet", trials=2)) == 2  # not empty: refused without --force
    assert main(compare_args(out, "--quiet", "--force", trials=2)) == 0
    for name in ("figures/errors_lu2014.png", "figures/errors_lu2014.svg", "report.html", "fields.csv"):
        assert not (out / name).exists(), name
    assert (out / CHECKPOINT).read_text() != "old\n"  # the new campaign's own record
    for name in mine:
        assert (out / name).read_text() == "old\n", name
    assert (out / "summary.tex").read_text() != "old\n" and (out / "traces.csv").read_text() != "old\n"
    assert json.loads((out / "manifest.json").read_text())["complete"] is True


# ------------------------------------------------------------------ integrity: lock and checksums
def _small(out, *extra):
    return ["compare", "--scenarios", "sphere9", "--methods", "lsq", "--trials", "3", "--seed", "5", "--out", str(out),
            "--no-figures", "--quiet", *extra]


def test_a_second_campaign_on_a_locked_folder_is_refused_naming_the_holder(tmp_path, capsys):
    from magbench.benchmarks.campaign import LOCK, campaign_lock

    out = tmp_path / "camp"
    with campaign_lock(out, "magbench compare --the-first-one"):
        capsys.readouterr()
        assert main(_small(out)) == 2
        captured = capsys.readouterr()
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1 and "in use by another campaign" in lines[0], lines
        assert f"process {os.getpid()}" in lines[0] and "--the-first-one" in lines[0]
        assert captured.out == ""
        assert sorted(os.listdir(out)) == [LOCK]  # nothing written by the refused one
    assert not (out / LOCK).exists()  # released
    assert main(_small(out)) == 0  # negative control: free again


def test_a_lock_left_by_a_dead_process_is_taken_over(tmp_path):
    from magbench.benchmarks.campaign import LOCK

    out = tmp_path / "camp"
    out.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (out / LOCK).write_text(json.dumps({"pid": int(dead.stdout), "host": "here", "command": "magbench compare"}))
    assert main(_small(out)) == 0
    assert json.loads((out / "manifest.json").read_text())["complete"] is True and not (out / LOCK).exists()


def _interrupted_checkpoint(tmp_path, monkeypatch, n_done=3):
    real, calls = campaign_module.run_task, []

    def interrupted(task):
        calls.append(task)
        if len(calls) == n_done + 1:
            raise KeyboardInterrupt
        return real(task)

    camp = Campaign(("sphere9",), (MethodSpec("lsq"),), trials=5, seed=5)
    monkeypatch.setattr(campaign_module, "run_task", interrupted)
    with pytest.raises(CampaignInterrupted):
        run_campaign(camp, tmp_path, progress=False)
    monkeypatch.setattr(campaign_module, "run_task", real)
    return camp


def test_tampered_and_foreign_checkpoint_lines_are_rerun_with_a_warning(tmp_path, monkeypatch, capsys):
    camp = _interrupted_checkpoint(tmp_path, monkeypatch)
    lines = (tmp_path / CHECKPOINT).read_text().splitlines()
    assert len(lines) == 4 and all("sha256" in json.loads(ln) for ln in lines[1:])
    tampered = json.loads(lines[1])
    tampered["row"]["rms_after_nT"] = 0.001  # well-formed, plausible, and false
    other = Campaign(("sphere9",), (MethodSpec("lsq"),), trials=5, seed=6)  # a line of another campaign
    foreign = json.loads(lines[2])
    from magbench.benchmarks.campaign import campaign_digest, line_checksum

    foreign["sha256"] = line_checksum(campaign_digest(other.definition()), foreign["key"], foreign["row"])
    edited = [lines[0], json.dumps(tampered), json.dumps(foreign), lines[3]]
    (tmp_path / CHECKPOINT).write_text("\n".join(edited) + "\n")
    header, done, refused = Checkpoint.read_checked(tmp_path / CHECKPOINT)
    assert refused == 2 and len(done) == 1
    capsys.readouterr()
    runs = run_campaign(camp, tmp_path, progress=False, resume=True)
    err = capsys.readouterr().err
    assert "2 line(s)" in err and "failed their checksum" in err
    assert (runs.attrs["n_resumed"], runs.attrs["n_new"]) == (1, 4)
    assert 0.001 not in set(runs["rms_after_nT"])


def test_a_corrupt_checkpoint_header_is_named_as_such(tmp_path, monkeypatch, capsys):
    _interrupted_checkpoint(tmp_path, monkeypatch)
    path = tmp_path / CHECKPOINT
    lines = path.read_text().splitlines()
    path.write_text("\n".join(['{"garbage": tru'] + lines[1:]) + "\n")
    saved = path.read_bytes()
    args = ["compare", "--scenarios", "sphere9", "--methods", "lsq", "--trials", "5", "--seed", "5", "--out",
            str(tmp_path), "--no-figures", "--quiet", "--resume"]
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is not a magbench checkpoint header" in err[0] and "no runs.partial" not in err[0]
    assert path.read_bytes() == saved


def test_a_campaign_started_while_another_process_runs_one_is_refused(tmp_path, capsys):
    """The race of two real processes: the second campaign (another seed, --force) on the
    folder of a running one exits 2 naming it, and the running one's checkpoint is untouched."""
    out = tmp_path / "camp"
    proc = start(compare_args(out, "--quiet"), tmp_path, "first")
    try:
        wait_for_runs(proc, out, 1)
        capsys.readouterr()
        assert main(compare_args(out, "--force", "--quiet", seed=SEED + 1)) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "in use by another campaign" in err[0] and f"process {proc.pid}" in err[0], err
        assert (out / CHECKPOINT).is_file()  # --force did not clear the running campaign's outputs
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=60) == 130
    finally:
        if proc.poll() is None:
            proc.kill()
    header, done = Checkpoint.read(out / CHECKPOINT)
    assert header["campaign"]["seed"] == SEED and done


def test_a_damaged_runs_table_is_refused_by_report_and_rebuilt_by_resume(tmp_path, capsys):
    """A hand-edited runs.csv (a row without scenario, configuration or whole trial) crashed ``report`` with an
    internal error, and ``--resume`` called the campaign complete, counting the row as a run.  Now ``report`` refuses
    it in one line (exit 2) naming the line; ``--resume`` rebuilds the tables from the checkpoint (the same runs as
    before the edit), and refuses (exit 2) when there is no checkpoint to rebuild from.  Negative control: the
    intact table is reported."""
    out = tmp_path / "camp"
    assert main(_small(out)) == 0
    good = pd.read_csv(out / "runs.csv")
    assert main(["report", str(out), "--quiet"]) == 0
    capsys.readouterr()
    for damage in ("garbage,,,\n", "sphere9,lsq,lsq,nine,two" + "," * (len(good.columns) - 5) + "\n"):
        with (out / "runs.csv").open("a") as fh:
            fh.write(damage)
        assert main(["report", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and f"line {len(good) + 2}" in err and "Traceback" not in err
        assert main(_small(out, "--resume")) == 0
        rebuilt = pd.read_csv(out / "runs.csv")
        assert len(rebuilt) == len(good) and rebuilt["trial"].tolist() == good["trial"].tolist()
    with (out / "runs.csv").open("a") as fh:
        fh.write("garbage,,,\n")
    (out / CHECKPOINT).unlink()
    capsys.readouterr()
    assert main(_small(out, "--resume")) == 2
    assert "no " + CHECKPOINT in capsys.readouterr().err
