"""The shipped recordings from any folder (`magbench data`, `example:NAME`), and the words a reader sees:
the demo says why a calibration is rejected; tables define finished and accepted; papers by author."""
from __future__ import annotations

import json

from magbench.benchmarks.cli import main


def test_data_lists_every_shipped_recording_with_its_path(capsys):
    assert main(["data", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert {"sap6_BB", "lu2014_table2"} <= set(listed)
    assert all(v["path"].endswith(f"{k}.csv") and v["title"] for k, v in listed.items())


def test_an_example_calibrates_from_another_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["calibrate", "example:sap6_BB", "--units", "uT", "--method", "lsq", "--json"]) in (0, 3)
    out = json.loads(capsys.readouterr().out)
    assert out["n_points"] == 24


def test_an_unknown_example_is_one_line_naming_the_known_ones(capsys):
    assert main(["calibrate", "example:nope", "--method", "lsq"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "sap6_BB" in err and "magbench data" in err


def test_the_demo_gives_each_rejection_its_reason(capsys):
    assert main(["demo"]) == 0
    out = capsys.readouterr().out
    rejected = [ln for ln in out.splitlines() if " REJECTED: " in ln]
    in_table = sum(ln.rstrip().endswith("REJECTED") for ln in out.splitlines())
    assert in_table and len(rejected) == in_table  # one reason line per rejected row
    assert all(": " in ln for ln in rejected)
    assert "Lu et al. 2014" in out and "seed 000" not in out
    assert "max_d_scale" in out and "largest over the" in out
    # the RMS before calibration, equal for every method of a scenario, is said once above its table
    assert out.count("total-field RMS before calibration: ") == 2 and "rms_before_nT" not in out
    table = [ln for ln in out.splitlines() if ln.startswith(("   method ", "      lsq "))]
    assert len(table) == 4 and max(len(ln) for ln in table) <= 110


def test_summary_tables_define_finished_and_accepted(tmp_path, capsys):
    out = tmp_path / "c"
    assert main(["compare", "--scenarios", "lu2014", "--methods", "lsq", "--trials", "2", "--out", str(out), "--quiet",
                 "--no-figures"]) == 0
    md = (out / "summary.md").read_text()
    assert "finished %" in md and "accepted %" in md and "success %" not in md
    assert "Finished: runs whose solver ended normally" in md and "max offset error" in md


def test_the_terminal_gets_a_compact_table(tmp_path, capsys):
    out = tmp_path / "c"
    assert main(["compare", "--scenarios", "lu2014", "--methods", "lsq", "ga:budget=1000", "--trials", "2", "--out",
                 str(out), "--quiet", "--no-figures"]) == 0
    text = capsys.readouterr().out
    table = text.split("fin: ")[0].splitlines()
    assert max(len(ln) for ln in table) <= 100 and "|" not in text
    assert "fin%" in text and "acc%" in text and "summary.md" in text


def test_user_facing_text_names_papers_by_author_not_by_seed_number(capsys):
    """`list`, every command's help and the README name the source papers by author (and year where our
    copy gives it), never by the project's internal "seed 00N" numbering."""
    import contextlib
    import re
    from pathlib import Path

    seen = []
    for argv in (["list"], ["--help"], ["gradiometer", "--help"], ["compare", "--help"], ["diagnose", "--help"],
                 ["calibrate", "--help"], ["reproduce", "--help"]):
        with contextlib.suppress(SystemExit):
            main(argv)
        seen.append(capsys.readouterr().out)
    seen.append(Path(__file__).resolve().parents[1].joinpath("README.md").read_text())
    text = "\n".join(seen)
    assert "Lu et al. 2014" in text and "Jin, Zhuang & Wang" in text
    assert not re.search(r"seeds? 00\d", text, re.IGNORECASE), re.findall(r".{40}seeds? 00\d.{20}", text, re.I)
