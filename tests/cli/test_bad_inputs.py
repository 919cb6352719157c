"""Issue 8: bad input, numerically wrong runs, and scene paths that stay paths.

* Every case of the bad-input corpus (tests/bad_inputs/corpus.py) through the command line's
  `main()` in this process, and a representative dozen through a real `python -m pounding_sweep`
  process: exit status 2, exactly one stderr line `error: ...` naming the file, key or line and
  the value, no traceback, and the case's folder left exactly as it was. Each message must also
  be the one recorded in tests/bad_inputs/OUTCOMES.md (the outcome table).
* A sweep in which some runs diverge finishes; those rows say `diverged`, the others `ok`.
* Relative paths in a scene resolve against the scene's folder, whatever the working folder;
  scene strings are never executed and files are never unpickled (only AT2/CSV records, CSV/Parquet
  tables and videos are read).
"""

from __future__ import annotations

import pickle
import re
import subprocess
import sys
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from bad_inputs.corpus import (
    BASE,
    CASES,
    GOOD_AT2,
    TABLE_SECTION,
    edit,
    fresh_dir,
    problems,
    record_scene,
    run_in_process,
    run_subprocess,
    table_csv,
)
from bad_inputs.make_outcomes import OUTCOMES, render_row, row_ids, rows_by_id
from conftest import REPO
from gates import SAFETY_S

BY_ID = {c.id: c for c in CASES}
INDEX = {c.id: i for i, c in enumerate(CASES, 1)}
ROWS = rows_by_id(OUTCOMES.read_text()) if OUTCOMES.exists() else {}
STALE = "OUTCOMES.md is not current: run python tests/bad_inputs/make_outcomes.py and review the diff"


# ------------------------------------------------------------------ the corpus itself


def test_corpus_covers_the_issue():
    ids = [c.id for c in CASES]
    assert len(ids) == len(set(ids)) >= 60
    for c in CASES:
        assert c.where and c.value, f"{c.id}: a case names both where (file/key/line) and the value"
    counts = Counter(c.category for c in CASES)
    assert set(counts) == {
        "toml",
        "keys",
        "types",
        "values",
        "grid",
        "record",
        "table",
        "video",
        "output",  # issue 17: where results go,
        "resume",  # what an existing result folder holds,
        "execution",  # and how the sweep runs
        "calibrate",  # issue 25: [calibrate] before the grid,
        "commands",  # and the other commands' outputs and options
        "risk",  # issue 29: ensembles, [stochastic], [risk] and the risk subcommand
    }
    assert min(counts.values()) >= 5, counts
    assert 10 <= sum(c.subprocess for c in CASES) <= 19  # the real-process dozen and a half (and one for risk)
    assert {c.category for c in CASES if c.subprocess} == set(counts)  # one of each kind at least


def test_outcome_table_lists_every_case_in_order():
    assert row_ids(OUTCOMES.read_text()) == [c.id for c in CASES], STALE


# ------------------------------------------------------------------ every case, in process


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_bad_input(case, tmp_path):
    d = fresh_dir(tmp_path, case)
    o = run_in_process(case, d)
    assert not problems(case, o, d), (problems(case, o, d), o.stderr)
    assert o.stdout == ""
    assert ROWS.get(case.id) == render_row(INDEX[case.id], case, o.code, o.message(d)), STALE


# ------------------------------------------------------------------ a dozen through the real command


@pytest.fixture(scope="module")
def real_runs(tmp_path_factory):
    """The subprocess cases, two processes at a time (each costs an interpreter with NumPy, pandas, Numba)."""
    root = tmp_path_factory.mktemp("real")
    cases = [c for c in CASES if c.subprocess]
    dirs = {c.id: fresh_dir(root, c) for c in cases}
    with ThreadPoolExecutor(2) as pool:
        # the timeout a safety net only: a bad input ends its command at once, however loaded the machine
        outcomes = dict(zip(dirs, pool.map(lambda c: run_subprocess(c, dirs[c.id], timeout=SAFETY_S), cases)))
    return {k: (outcomes[k], dirs[k]) for k in dirs}


@pytest.mark.parametrize("case", [c for c in CASES if c.subprocess], ids=lambda c: c.id)
def test_bad_input_real_command(case, real_runs):
    o, d = real_runs[case.id]
    assert not problems(case, o, d), (problems(case, o, d), o.stderr)
    assert o.stdout == ""
    # the real process prints what main() printed in process (so the in-process runs stand for it)
    assert ROWS.get(case.id) == render_row(INDEX[case.id], case, o.code, o.message(d)), STALE


def test_a_scene_error_is_reported_before_the_engine_is_loaded(tmp_path):
    """A scene that fails to load never imports Numba, pyarrow or SciPy (about 1 s of start-up here)."""
    scene = tmp_path / "bad.toml"
    scene.write_text(BASE.replace("r = [0.2, 0.6]", "r = [0.2, 1.5]"))
    code = (
        "import sys; from pounding_sweep.cli import main; rc = main([sys.argv[1]]); "
        "print(rc, [m for m in ('numba', 'pyarrow', 'scipy') if m in sys.modules])"
    )
    p = subprocess.run([sys.executable, "-c", code, str(scene)], capture_output=True, text=True, cwd=REPO)
    assert p.stdout.strip() == "2 []", (p.stdout, p.stderr)
    assert "r" in p.stderr and "1.5" in p.stderr


# ------------------------------------------------------------------ runs that go numerically wrong


def test_diverging_runs_are_flagged_and_the_sweep_goes_on(tmp_path):
    """The paper's scheme at a coarse dt: the stiff-contact half of the grid blows up, the soft half
    does not. The sweep finishes (exit 0), every grid point has exactly one row, blown-up rows say
    `diverged` (and stopped early), the others are `ok` with finite metrics."""
    from pounding_sweep.cli.run import main

    text = edit(
        edit(edit(BASE, 'scheme = "event"', 'scheme = "paper"'), "dt_s = 1e-4", "dt_s = 2e-3"),
        "ks_ratio = [0.1, 1.0]",
        "ks_ratio = [0.1, 1.0, 1000.0, 10000.0]",
    )
    text = edit(text, "duration_s = 0.2", "duration_s = 1.0") + "\n[execution]\nchunk_runs = 3\n"
    (tmp_path / "scene.toml").write_text(text)
    assert main([str(tmp_path / "scene.toml"), "--quiet", "--threads", "1"]) == 0
    df = pd.read_parquet(tmp_path / "out.parquet")
    assert df.run_id.tolist() == list(range(8))
    stiff = df.ks_ratio >= 1000
    assert df.status[stiff].str.contains("diverged").all()
    assert (df.status[~stiff] == "ok").all()
    assert (df.steps[stiff] < df.steps[~stiff].min()).all()  # integration stopped at the blow-up
    metrics = df.loc[~stiff].select_dtypes("number")
    assert np.isfinite(metrics.to_numpy()).all()
    # energy made by the numerics is flagged wherever it exceeds 1 % of the input work
    made = df.energy_residual_J.abs() > 0.01 * df.input_work_abs_J
    assert made[stiff].all() and df.status[made].str.contains("energy_residual").all()


# ------------------------------------------------------------------ paths: relative to the scene, never code


def test_relative_paths_resolve_against_the_scene_folder_from_any_cwd(tmp_path, monkeypatch):
    """Record, experiment table and output are named relative to the scene file; the command is run
    from an unrelated folder with a relative scene path. Everything is found, and the results land
    beside the scene, nothing in the working folder."""
    from pounding_sweep.cli.run import main

    scenes, data, elsewhere = tmp_path / "project" / "scenes", tmp_path / "project" / "data", tmp_path / "elsewhere"
    for d in (scenes, data, elsewhere):
        d.mkdir(parents=True)
    (data / "rec.AT2").write_text(GOOD_AT2)
    (data / "exp.csv").write_text(table_csv(rows=10))
    text = edit(record_scene("../data/rec.AT2"), 'path = "out.parquet"', 'path = "../results/out.parquet"')
    (scenes / "scene.toml").write_text(text + TABLE_SECTION.format(table="../data/exp.csv"))
    monkeypatch.chdir(elsewhere)
    assert main(["../project/scenes/scene.toml", "--quiet", "--threads", "1"]) == 0
    out = tmp_path / "project" / "results" / "out.parquet"
    df = pd.read_parquet(out)
    assert len(df) == 4 and set(df.record) == {"rec"} and np.isfinite(df.rel_rms_combined_pct).all()
    assert list(elsewhere.iterdir()) == []


class _Touch:
    """Unpickling this creates `path`: the proof that nothing unpickles."""

    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        return (Path.touch, (Path(self.path),))


def test_scene_strings_are_never_executed_and_files_never_unpickled(tmp_path):
    """YAML tags, Python expressions and pickles in a scene or its files are inert: strings stay
    strings, a pickle is refused by name (.pkl) or read as the text/Parquet/video it claims to be."""
    from pounding_sweep.cli.run import main
    from pounding_sweep.scene import ConfigError, load_scene

    marker = tmp_path / "PWNED"
    payload = pickle.dumps(_Touch(marker))
    assert not marker.exists()
    # strings that would run code if anything evaluated them
    evil = [f'!!python/object/apply:os.system ["touch {marker}"]', f"__import__('pathlib').Path('{marker}').touch()"]
    for e in evil:
        (tmp_path / "s.toml").write_text(
            edit(BASE, 'name = "bad_input_case"', f'name = "bad_input_case"\ndescription = {e!r}')
        )
        assert load_scene(tmp_path / "s.toml").description == e  # a plain string
        (tmp_path / "s.toml").write_text(edit(BASE, 'name = "bad_input_case"', f"name = {e!r}"))
        with pytest.raises(ConfigError, match="no path separators"):  # names become file names: refused
            load_scene(tmp_path / "s.toml")
    # a pickle as record, table and video, by its own name and disguised as each format
    for name in ("rec.pkl", "rec.AT2", "rec.csv", "exp.pkl", "exp.csv", "exp.parquet", "run.pkl", "run.mkv"):
        (tmp_path / name).write_bytes(payload)
    scenes = {
        "rec.pkl": record_scene("rec.pkl"),
        "rec.AT2": record_scene("rec.AT2"),
        "rec.csv": record_scene("rec.csv"),
        "rec.pkl as csv": record_scene("rec.pkl", 'format = "csv"\n'),
    }
    scenes.update({t: BASE + TABLE_SECTION.format(table=t) for t in ("exp.pkl", "exp.csv", "exp.parquet")})
    for i, (what, scene_text) in enumerate(scenes.items()):
        (tmp_path / f"{i}.toml").write_text(scene_text)
        assert main([str(tmp_path / f"{i}.toml"), "--out", str(tmp_path / "out.parquet"), "--quiet"]) == 2, what
    for video in ("run.pkl", "run.mkv"):
        pytest.importorskip("cv2")
        assert (
            main(
                [
                    "track",
                    str(tmp_path / video),
                    "--markers",
                    "table_left,b1f1",
                    "--references",
                    "table_left",
                    "--mm-per-px",
                    "1",
                    "--out",
                    str(tmp_path / "t.csv"),
                    "--quiet",
                ]
            )
            == 2
        )
    assert not marker.exists()
    assert not (tmp_path / "out.parquet").exists() and not (tmp_path / "t.csv").exists()


# Reading user files: these calls only. A new reader (or pickle, eval, YAML) must be added here on purpose.
ALLOWED_READERS = {
    "pd.read_csv": {"model/experiment.py", "model/sensors/formats.py", "plots.py"},  # sensor exports: dtype=float
    "pd.read_parquet": {"plots.py"},  # result files the sweep wrote
    # tables; our own parts (read back, and rewritten to store warnings); our best table (a stored refinement or
    # calibration reused); the track cache
    "pq.read_table": {
        "model/experiment.py",
        "sweep/run.py",
        "sweep/best.py",
        "sweep/results.py",
        "video/tracker.py",
        "risk/study.py",
    },
    "pq.read_schema": {"model/experiment.py", "sweep/results.py"},  # a table's column names; our own parts
    # footers: parts, the best-runs file, a tracked table (track --out) and a gap study's table (gaps --out), as ours
    "pq.read_metadata": {"sweep/results.py", "sweep/resume.py", "cli/track.py", "cli/gaps.py"},
    "cv2.VideoCapture": {"video/io.py"},
}
FORBIDDEN = (
    r"\bpickle\b|\beval\(|\bexec\(|__import__|\bmarshal\b|\bshelve\b|\bjoblib\b|\bdill\b|yaml|allow_pickle|"
    r"\bnp\.load\(|read_pickle|read_excel|read_html|read_sql|read_json|read_feather|read_hdf|\bsubprocess\b|os\.system"
)


#: the one exception, on purpose: engine/aside.py starts its own module (`sys.executable -m
#: pounding_sweep.engine.aside`, no shell, no user input) to compile kernel pieces beside this process, and
#: hands it the pieces' Numba types, which only pickle, over a pipe from this process: nothing a user wrote
EXCEPTIONS = {"engine/aside.py": {"subprocess", "pickle"}}


def test_no_reader_can_run_code():
    """Static check of the package: nothing unpickles, evaluates or shells out (but EXCEPTIONS), and the only
    file readers are the listed ones (AT2/CSV records are parsed by hand in records.py)."""
    found: dict[str, set[str]] = {}
    for py in sorted((REPO / "pounding_sweep").rglob("*.py")):
        code = "\n".join(line.split("#")[0] for line in py.read_text().splitlines())
        name = py.relative_to(REPO / "pounding_sweep").as_posix()
        bad = set(re.findall(FORBIDDEN, code)) - EXCEPTIONS.get(name, set())
        assert not bad, f"{name}: {sorted(bad)}"
        for call in re.findall(r"\b(?:pd|pq|pa|np|cv2|ds)\.(?:read_\w+|load\w*|VideoCapture)\b", code):
            found.setdefault(call, set()).add(name)
    assert set(found) <= set(ALLOWED_READERS), found
    for call, files in found.items():
        assert files <= ALLOWED_READERS[call], (call, files)


@pytest.mark.parametrize(
    "argv, said",
    [
        (["gaps", "s.toml", "--relative-gaps", "-1,0.5"], "write --relative-gaps=-1,0.5"),
        (["s.toml", "--threads"], "argument --threads: expected one argument (see --help)"),
        (["s.toml", "--bogus"], "unrecognized arguments: --bogus"),
        (["risk"], "the following arguments are required: scene"),
    ],
)
def test_a_command_line_argparse_refuses_is_one_line(argv, said, capsys):
    """cli/common.py OneLineParser: what argparse refuses is one `error: ...` line with exit status 2, no usage
    block (a helper's `--relative-gaps -1,0.5` got the multi-line usage); a value that starts with '-' is told
    how to write it."""
    from pounding_sweep.cli import main

    with pytest.raises(SystemExit) as e:
        main(argv)
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("\n") == 1 and err.startswith("error: python -m pounding_sweep")
    assert said in err
