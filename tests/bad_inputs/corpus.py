"""The bad-input corpus of issue 8: every case, what it feeds the command line, and what the one
error line must name. This table is the only place a case is defined; `tests/cli/test_bad_inputs.py`
runs every case, `make_outcomes.py` writes the message each case gets into OUTCOMES.md.

A case is a small generated file set in its own folder: `scene.toml` (the base scene below with
one fault, or no scene at all) plus the record, table or video it refers to. Videos are rendered
on the fly (40 frames at 320x240, about 1 MB, never stored in git) or written as bytes.

Every case must end with exit status 2, exactly one stderr line `error: ...` that contains every
`where` fragment (the file, key or line) and every `value` fragment (the offending value), and the
case folder exactly as it was before the run (no result folder, part, `.tmp` or table).
"""

from __future__ import annotations

import contextlib
import functools
import io
import os
import shutil
import subprocess
import sys
import traceback
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
EXIT_BAD_INPUT = 2

# ----------------------------------------------------------------------------- base inputs

BASE = """\
name = "bad_input_case"

[building1]
masses_kg = [1.7, 1.7, 1.6]
story_stiffness_N_per_m = 5920.0
damping_ratio = 0.0105

[building2]
masses_kg = [0.56, 0.56, 0.45]
story_stiffness_N_per_m = 5140.0
damping_ratio = 0.0107

[contact]
gap_m = 0.0
ks_ratio = 1.0
r = 0.4
law = "classic"

[excitation]
type = "harmonic"
amplitude_m = 0.002
frequency_Hz = 6.0
duration_s = 0.2

[integration]
dt_s = 1e-4
scheme = "event"

[sweep]
ks_ratio = [0.1, 1.0]
r = [0.2, 0.6]

[output]
path = "out.parquet"
"""

CONTACT = """\
[contact]
gap_m = 0.0
ks_ratio = 1.0
r = 0.4
law = "classic"
"""

HARMONIC = """\
[excitation]
type = "harmonic"
amplitude_m = 0.002
frequency_Hz = 6.0
duration_s = 0.2
"""


def edit(text: str, old: str, new: str) -> str:
    """`text` with the one occurrence of `old` replaced (a case's fault)."""
    assert text.count(old) == 1, f"{old!r} occurs {text.count(old)} times"
    return text.replace(old, new)


def line_of(text: str, snippet: str) -> int:
    """1-based line number of the line holding `snippet`."""
    for i, line in enumerate(text.splitlines(), 1):
        if snippet in line:
            return i
    raise AssertionError(snippet)


def record_scene(name: str = "rec.AT2", extra: str = "") -> str:
    return edit(BASE, HARMONIC, f'[excitation]\ntype = "record"\nrecord = "{name}"\n{extra}')


TABLE_SECTION = """
[experiment]
table = "{table}"
time_column = "t_s"
units = "mm"
channels = {{ b1f3 = "b1f3", b2f3 = "b2f3" }}
max_lag_s = 0.05
"""


def table_scene(table: str = "exp.csv") -> str:
    return BASE + TABLE_SECTION.format(table=table)


BUILDING2 = """\
[building2]
masses_kg = [0.56, 0.56, 0.45]
story_stiffness_N_per_m = 5140.0
damping_ratio = 0.0107

"""


def single_building(text: str, sweep: str | None = None) -> str:
    """`text` as a single-building scene: no [building2], no [contact]; its [sweep] replaced by `sweep`."""
    out = edit(edit(text, BUILDING2, ""), CONTACT, "")
    if sweep is not None:
        out = edit(out, "ks_ratio = [0.1, 1.0]\nr = [0.2, 0.6]\n", sweep)
    return out


MARKERS = ["table_left", "table_right", "b1f1", "b1f2", "b1f3", "b2f1", "b2f2", "b2f3"]
VIDEO_SECTION = """
[experiment]
units = "mm"
max_lag_s = 0.05

[experiment.video]
path = "{video}"
markers = [{markers}]
references = ["table_left", "table_right"]
mm_per_px = 5.0
"""


def video_scene(video: str = "run.mkv") -> str:
    return BASE + VIDEO_SECTION.format(video=video, markers=", ".join(f'"{m}"' for m in MARKERS))


TRACK = (
    "track",
    "{dir}/{video}",
    "--markers",
    ",".join(MARKERS),
    "--references",
    "table_left,table_right",
    "--mm-per-px",
    "5",
    "--out",
    "{dir}/tracked.csv",
    "--quiet",
)


def track(video: str = "run.mkv", *extra: str) -> tuple[str, ...]:
    return tuple(a.replace("{video}", video) for a in TRACK) + extra


GOOD_AT2 = """\
PEER NGA STRONG MOTION DATABASE RECORD
SYNTHETIC 2024, TEST STATION, 000
ACCELERATION TIME SERIES IN UNITS OF G
NPTS=   10, DT=   .0100 SEC
  .1000000E-01  .2000000E-01  .3000000E-01  .2000000E-01  .1000000E-01
 -.1000000E-01 -.2000000E-01 -.3000000E-01 -.2000000E-01 -.1000000E-01
"""

GOOD_CSV_RECORD = "t_s,acc_m_s2\n" + "".join(f"{0.01 * i:.2f},{0.1 * (i % 3):.1f}\n" for i in range(10))


def table_csv(rows: int = 21, t=None, b1=None, b2=None, header: str = "t_s,b1f3,b2f3") -> str:
    """A tracked-displacement CSV (0.01 s step); t/b1/b2 override single cells: {row: 'text'}."""
    lines = [header]
    for i in range(rows):
        cells = [f"{0.01 * i:.2f}", f"{0.1 * np.sin(i):.4f}", f"{-0.1 * np.sin(i):.4f}"]
        for col, over in enumerate((t, b1, b2)):
            if over and i in over:
                cells[col] = over[i]
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- raw sensor exports (issue 27)


def xsens_csv(
    rows: int = 64, ticks=None, acc_x=None, tag: str = "Xsens DOT", gain: float = 0.5, g: float = 9.81
) -> str:
    """A small Xsens DOT export (120 Hz, Acc_X gain * sin(0.3 i), gravity g on Z): overrides {row: 'text'} for
    SampleTimeFine or Acc_X."""
    head = (
        f"sep=,\nDeviceTag:,{tag}\nFirmwareVersion:,3.0.0\nAppVersion:,2023.6.0\n"
        "StartTime: ,2025-03-06_12:43:39_000 PST\n\u00a9 Movella Technologies B. V. 2005-2025\n\n"
        "PacketCounter,SampleTimeFine,Euler_X,Euler_Y,Euler_Z,Acc_X,Acc_Y,Acc_Z,Gyr_X,Gyr_Y,Gyr_Z\n"
    )
    lines = []
    for i in range(rows):
        tick = (ticks or {}).get(i, str(2042652963 + 8333 * i))
        ax = (acc_x or {}).get(i, f"{gain * np.sin(0.3 * i):.5f}")
        lines.append(f"{i},{tick},1.0,2.0,3.0,{ax},0.01,{g},0.0,0.0,0.0")
    return head + "\n".join(lines) + "\n"


def import_argv(*extra: str, names=("ground", "b1f1")) -> tuple[str, ...]:
    return ("import", *[f"{n}={{dir}}/{n}.csv" for n in names], "--out", "{dir}/imported", *extra)


XSENS_PAIR = {"ground.csv": xsens_csv(), "b1f1.csv": xsens_csv(tag="floor", gain=0.7)}


PICKLE = b"\x80\x04K\x01."  # pickle.dumps(1, protocol=4): bytes a reader must never unpickle


def _parquet_bytes(columns: dict) -> bytes:
    import pyarrow as pa
    import pyarrow.parquet as pq

    buf = io.BytesIO()
    pq.write_table(pa.table(columns), buf)
    return buf.getvalue()


# ----------------------------------------------------------------------------- videos (generated)


@functools.lru_cache(maxsize=1)
def rendered_video() -> bytes:
    """A tiny good shake-table video (FFV1 .mkv, 40 frames at 320x240, 100 fps), made once per process."""
    import tempfile

    from pounding_sweep.video.render import RenderOptions, harmonic_table, render_video, shake_table_layout

    def motion(t):
        t = np.asarray(t, dtype=float)
        out = {"table": harmonic_table(1.0, 6.0)(t)}
        for b in (1, 2):
            for f in (1, 2, 3):
                out[f"b{b}f{f}"] = 1.5 * f * np.sin(2 * np.pi * 4.25 * t)
        return out

    with tempfile.TemporaryDirectory() as d:
        v = render_video(Path(d) / "run.mkv", shake_table_layout(), motion, 40, RenderOptions(noise=1.0, seed=8))
        return v.path.read_bytes()


def video_head(n_bytes: int) -> Callable[[], bytes]:
    """The first n bytes of the good video: a download or copy cut short."""
    return lambda: rendered_video()[:n_bytes]


def video_fraction(frac: float) -> Callable[[], bytes]:
    return lambda: rendered_video()[: int(len(rendered_video()) * frac)]


def png_still() -> bytes:
    from pounding_sweep.video.io import cv2_module

    ok, buf = cv2_module().imencode(".png", np.zeros((48, 64, 3), np.uint8))
    assert ok
    return buf.tobytes()


# ----------------------------------------------------------------------------- special files, result folders


@dataclass(frozen=True)
class Symlink:
    """A symbolic link to `target` (relative to the link's folder)."""

    target: str


@dataclass(frozen=True)
class Fifo:
    """A named pipe: a reader that opens it waits for a writer that never comes."""


@dataclass(frozen=True)
class Sparse:
    """A file of `size` zero bytes that takes no disk space (only its stated size matters)."""

    size: int


#: a scene of 4 runs in 2 parts, and the same at another dt: the sweeps whose result folders the
#: resume cases start from (a real manifest and real parts, made once per process)
RESUMABLE = BASE + "\n[execution]\nchunk_runs = 2\n"
OTHER_DT = edit(RESUMABLE, "dt_s = 1e-4", "dt_s = 2e-4")


@functools.lru_cache(maxsize=4)
def result_files(scene_text: str) -> dict[str, bytes]:
    """The files of the result folder a sweep of `scene_text` writes, by name."""
    import tempfile

    from pounding_sweep.scene import load_scene
    from pounding_sweep.sweep.run import run_scene

    with tempfile.TemporaryDirectory() as d:
        (Path(d) / "scene.toml").write_text(scene_text)
        run_scene(load_scene(Path(d) / "scene.toml"), out_path=Path(d) / "out.parquet", threads=1)
        return {p.name: p.read_bytes() for p in (Path(d) / "out.parquet").iterdir()}


def result(scene_text: str, name: str, change: Callable[[bytes], bytes] = lambda b: b) -> Callable[[], bytes]:
    """One file of that folder, perhaps changed (cut short, say)."""
    return lambda: change(result_files(scene_text)[name])


def result_folder(changes: dict | None = None, scene_text: str = RESUMABLE) -> dict:
    """`out.parquet/` as a sweep of `scene_text` left it, some files replaced ({name: content, None: dropped})."""
    names = ("_sweep.json", "part-00000.parquet", "part-00001.parquet")
    files = {n: result(scene_text, n) for n in names}
    files.update(changes or {})
    return {f"out.parquet/{n}": c for n, c in files.items() if c is not None}


# ----------------------------------------------------------------------------- cases


@dataclass(frozen=True)
class Case:
    id: str
    category: str
    what: str  # the input, in words (the outcome table's "input" column)
    where: tuple[str, ...]  # fragments naming the file, key or line
    value: tuple[str, ...]  # fragments naming the offending value
    scene: str | bytes | None = BASE  # written to scene.toml (None: no scene file)
    files: dict = field(default_factory=dict)  # name -> text, bytes, callable -> bytes, or None (a folder)
    argv: tuple[str, ...] = ("{scene}", "--out", "{out}")
    subprocess: bool = False  # also run through a real `python -m pounding_sweep` process


def _c(id, category, what, where, value, scene=BASE, files=None, argv=("{scene}", "--out", "{out}"), sub=False):
    w = (where,) if isinstance(where, str) else tuple(where)
    v = (value,) if isinstance(value, str) else tuple(value)
    return Case(id, category, what, w, v, scene, dict(files or {}), tuple(argv), sub)


S = "scene.toml"
_L = functools.partial(line_of, BASE)

CASES: list[Case] = [
    # ------------------------------------------------------------------ the scene file and TOML syntax
    _c(
        "toml_double_equals",
        "toml",
        "`r = = 0.4`",
        [S, f"line {_L('r = 0.4')}"],
        "r = = 0.4",
        edit(BASE, "r = 0.4", "r = = 0.4"),
        sub=True,
    ),
    _c(
        "toml_unclosed_string",
        "toml",
        'name = "bad_input_case (no closing quote)',
        [S, "line 1"],
        'name = "bad_input_case',
        edit(BASE, 'name = "bad_input_case"', 'name = "bad_input_case'),
    ),
    _c(
        "toml_unclosed_array",
        "toml",
        "masses_kg = [1.7, 1.7, 1.6 (no ])",
        [S, "line"],
        "masses_kg = [1.7, 1.7, 1.6",
        edit(BASE, "masses_kg = [1.7, 1.7, 1.6]", "masses_kg = [1.7, 1.7, 1.6"),
    ),
    _c(
        "toml_duplicate_key",
        "toml",
        "`r` twice in [contact]",
        [S, f"line {_L('r = 0.4') + 1}"],
        "r = 0.5",
        edit(BASE, "r = 0.4\n", "r = 0.4\nr = 0.5\n"),
    ),
    _c(
        "toml_duplicate_table",
        "toml",
        "[contact] declared twice",
        [S, "line"],
        "[contact]",
        BASE + "\n[contact]\nr = 0.5\n",
    ),
    _c(
        "toml_bad_table_header",
        "toml",
        "`[sweep` (no closing bracket)",
        [S, f"line {_L('[sweep]')}"],
        "[sweep",
        edit(BASE, "[sweep]", "[sweep"),
    ),
    _c(
        "toml_two_values_on_a_line",
        "toml",
        "`dt_s = 1e-4 2e-4`",
        [S, f"line {_L('dt_s')}"],
        "dt_s = 1e-4 2e-4",
        edit(BASE, "dt_s = 1e-4", "dt_s = 1e-4 2e-4"),
    ),
    _c("scene_not_utf8", "toml", "scene file in UTF-16", [S], "not UTF-8", BASE.encode("utf-16"), sub=True),
    _c(
        "scene_missing",
        "toml",
        "scene file does not exist",
        ["nowhere.toml"],
        "No such file",
        None,
        argv=("{dir}/nowhere.toml", "--out", "{out}"),
    ),
    _c(
        "scene_is_a_folder",
        "toml",
        "scene path is a folder",
        ["scenes"],
        "Is a directory",
        None,
        files={"scenes": None},
        argv=("{dir}/scenes", "--out", "{out}"),
    ),
    _c("scene_empty", "toml", "empty scene file", [S], "[building1]", ""),
    # ------------------------------------------------------------------ unknown and misspelled keys
    _c(
        "misspelled_key",
        "keys",
        "`ks_ration` in [contact]",
        [S, "[contact]", "ks_ration"],
        "did you mean 'ks_ratio'",
        edit(BASE, "ks_ratio = 1.0", "ks_ration = 1.0"),
        sub=True,
    ),
    _c(
        "misspelled_section",
        "keys",
        "`[contcat]`",
        [S, "top level", "contcat"],
        "did you mean 'contact'",
        edit(BASE, "[contact]", "[contcat]"),
    ),
    _c(
        "misspelled_building_key",
        "keys",
        "`masses_kgs` in [building1]",
        [S, "[building1]", "masses_kgs"],
        "did you mean 'masses_kg'",
        edit(BASE, "masses_kg = [1.7, 1.7, 1.6]", "masses_kgs = [1.7, 1.7, 1.6]"),
    ),
    _c(
        "misspelled_integration_key",
        "keys",
        "`dt = 1e-4` in [integration]",
        [S, "[integration]", "'dt'"],
        "did you mean 'dt_s'",
        edit(BASE, "dt_s = 1e-4", "dt = 1e-4"),
    ),
    _c(
        "misspelled_sweep_axis",
        "keys",
        "`ks_ratios` axis",
        [S, "[sweep]", "ks_ratios"],
        "did you mean 'ks_ratio'",
        edit(BASE, "ks_ratio = [0.1, 1.0]", "ks_ratios = [0.1, 1.0]"),
    ),
    _c(
        "misspelled_range_key",
        "keys",
        "`r = {start, stop, nun}`",
        [S, "[sweep] r", "nun"],
        "did you mean 'num'",
        edit(BASE, "r = [0.2, 0.6]", "r = {start = 0.0, stop = 1.0, nun = 5}"),
    ),
    _c(
        "misspelled_execution_key",
        "keys",
        "`thread = 2` in [execution]",
        [S, "[execution]", "thread"],
        "did you mean 'threads'",
        BASE + "\n[execution]\nthread = 2\n",
    ),
    _c(
        "misspelled_output_key",
        "keys",
        "`history = [...]` in [output]",
        [S, "[output]", "history"],
        "did you mean 'histories'",
        BASE + 'history = ["disp_b1f3"]\n',
    ),
    _c(
        "misspelled_experiment_key",
        "keys",
        "`time_colum` in [experiment]",
        [S, "[experiment]", "time_colum"],
        "did you mean 'time_column'",
        edit(table_scene(), 'time_column = "t_s"', 'time_colum = "t_s"'),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "misspelled_video_key",
        "keys",
        "`mm_per_pixel` in [experiment.video]",
        [S, "[experiment.video]", "mm_per_pixel"],
        "did you mean 'mm_per_px'",
        edit(video_scene(), "mm_per_px = 5.0", "mm_per_pixel = 5.0"),
        files={"run.mkv": rendered_video},
    ),
    _c(
        "unknown_top_key",
        "keys",
        '`solver = "rk4"` at the top',
        [S, "top level", "solver"],
        "allowed:",
        'solver = "rk4"\n' + BASE,
    ),
    # ------------------------------------------------------------------ wrong types
    _c(
        "text_for_number",
        "types",
        'frequency_Hz = "6 Hz"',
        [S, "[excitation] frequency_Hz"],
        "'6 Hz'",
        edit(BASE, "frequency_Hz = 6.0", 'frequency_Hz = "6 Hz"'),
        sub=True,
    ),
    _c(
        "bool_for_number",
        "types",
        "amplitude_m = true",
        [S, "[excitation] amplitude_m"],
        "True",
        edit(BASE, "amplitude_m = 0.002", "amplitude_m = true"),
    ),
    _c(
        "date_for_number",
        "types",
        "duration_s = 2024-01-01",
        [S, "[excitation] duration_s"],
        "2024",
        edit(BASE, "duration_s = 0.2", "duration_s = 2024-01-01"),
    ),
    _c("number_for_text", "types", "law = 1", [S, "[contact] law"], "= 1", edit(BASE, 'law = "classic"', "law = 1")),
    _c(
        "list_for_scalar",
        "types",
        "r = [0.4] in [contact]",
        [S, "[contact] r"],
        "[0.4]",
        edit(BASE, "r = 0.4", "r = [0.4]"),
    ),
    _c(
        "text_for_list",
        "types",
        'masses_kg = "1.7, 1.7, 1.6"',
        [S, "[building1] masses_kg"],
        "'1.7, 1.7, 1.6'",
        edit(BASE, "masses_kg = [1.7, 1.7, 1.6]", 'masses_kg = "1.7, 1.7, 1.6"'),
    ),
    _c(
        "float_for_integer",
        "types",
        "history_decimate = 2.5",
        [S, "[output] history_decimate"],
        "2.5",
        BASE + "history_decimate = 2.5\n",
    ),
    _c(
        "section_as_value",
        "types",
        "contact = 5 instead of a [contact] table",
        [S, "'contact'"],
        "5",
        "contact = 5\n" + edit(BASE, CONTACT, ""),
    ),
    _c(
        "axis_as_text",
        "types",
        'r = "0.2 .. 1.0" in [sweep]',
        [S, "[sweep] r"],
        "'0.2 .. 1.0'",
        edit(BASE, "r = [0.2, 0.6]", 'r = "0.2 .. 1.0"'),
    ),
    _c(
        "channels_as_list",
        "types",
        'channels = ["b1f3"]',
        [S, "[experiment] channels"],
        "['b1f3']",
        edit(table_scene(), 'channels = { b1f3 = "b1f3", b2f3 = "b2f3" }', 'channels = ["b1f3"]'),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "text_for_bool",
        "types",
        'refine = "yes"',
        [S, "[experiment] refine"],
        "'yes'",
        table_scene() + 'refine = "yes"\n',
        files={"exp.csv": table_csv()},
    ),
    _c(
        "dt_word",
        "types",
        'dt_s = "fast"',
        [S, "[integration] dt_s"],
        "'fast'",
        edit(BASE, "dt_s = 1e-4", 'dt_s = "fast"'),
    ),
    # ------------------------------------------------------------------ out-of-range values
    _c(
        "scene_name_is_a_path",
        "values",
        "name = '../elsewhere' (the default output file name)",
        [S, "name"],
        "../elsewhere",
        edit(BASE, 'name = "bad_input_case"', 'name = "../elsewhere"'),
    ),
    _c(
        "unknown_metric_group",
        "values",
        '[output] metrics = ["energy", "drfit"] (a typo of drift)',
        [S, "[output] metrics"],
        "drfit",
        BASE + 'metrics = ["energy", "drfit"]\n',
    ),
    _c(
        "r_above_1",
        "values",
        "[contact] r = 1.5",
        [S, "[contact] r"],
        "1.5",
        edit(BASE, "r = 0.4", "r = 1.5"),
        sub=True,
    ),
    _c(
        "r_negative_in_sweep",
        "values",
        "[sweep] r = [0.2, -0.1]",
        [S, "[sweep] r"],
        "-0.1",
        edit(BASE, "r = [0.2, 0.6]", "r = [0.2, -0.1]"),
    ),
    _c(
        "r_range_past_1",
        "values",
        "[sweep] r = {0 .. 1.5, 4 values}",
        [S, "[sweep] r"],
        "1.5",
        edit(BASE, "r = [0.2, 0.6]", "r = {start = 0.0, stop = 1.5, num = 4}"),
    ),
    _c(
        "negative_gap",
        "values",
        "gap_m = -0.001",
        [S, "[contact] gap_m"],
        "-0.001",
        edit(BASE, "gap_m = 0.0", "gap_m = -0.001"),
    ),
    _c(
        "negative_gap_in_sweep",
        "values",
        "[sweep] gap_m = [0.0, -0.002]",
        [S, "[sweep] gap_m"],
        "-0.002",
        BASE.replace("[sweep]\n", "[sweep]\ngap_m = [0.0, -0.002]\n"),
    ),
    _c(
        "zero_mass",
        "values",
        "a floor mass of 0",
        [S, "[building2] masses_kg"],
        "0.0",
        edit(BASE, "masses_kg = [0.56, 0.56, 0.45]", "masses_kg = [0.56, 0, 0.45]"),
    ),
    _c(
        "negative_mass",
        "values",
        "a floor mass of -1.7",
        [S, "[building1] masses_kg"],
        "-1.7",
        edit(BASE, "masses_kg = [1.7, 1.7, 1.6]", "masses_kg = [1.7, -1.7, 1.6]"),
    ),
    _c(
        "zero_stiffness",
        "values",
        "story_stiffness_N_per_m = 0",
        [S, "[building1] story_stiffness_N_per_m"],
        "0.0",
        edit(BASE, "story_stiffness_N_per_m = 5920.0", "story_stiffness_N_per_m = 0"),
    ),
    _c(
        "negative_stiffness",
        "values",
        "story stiffness list with -5140",
        [S, "[building2] story_stiffness_N_per_m"],
        "-5140.0",
        edit(BASE, "story_stiffness_N_per_m = 5140.0", "story_stiffness_N_per_m = [5140.0, -5140.0, 5140.0]"),
    ),
    _c(
        "stiffness_overflow",
        "values",
        "story_stiffness_N_per_m = 1e308",
        [S, "[building1] story_stiffness_N_per_m"],
        "1e+308",
        edit(BASE, "story_stiffness_N_per_m = 5920.0", "story_stiffness_N_per_m = 1e308"),
    ),
    _c(
        "column_height_overflow",
        "values",
        "story_height_m = 1e200 (h^3 overflows)",
        [S, "[building2]", "story_height_m"],
        "1e+200",
        edit(BASE, "story_stiffness_N_per_m = 5140.0", "column_EI_Nm2 = 4.6\nn_columns = 4\nstory_height_m = 1e200"),
    ),
    _c(
        "zero_contact_stiffness",
        "values",
        "[sweep] ks_ratio = [0.0, 1.0]",
        [S, "[sweep] ks_ratio"],
        "0.0",
        edit(BASE, "ks_ratio = [0.1, 1.0]", "ks_ratio = [0.0, 1.0]"),
    ),
    _c("zero_dt", "values", "dt_s = 0", [S, "[integration] dt_s"], "0.0", edit(BASE, "dt_s = 1e-4", "dt_s = 0")),
    _c(
        "negative_dt",
        "values",
        "dt_s = -1e-4",
        [S, "[integration] dt_s"],
        "-0.0001",
        edit(BASE, "dt_s = 1e-4", "dt_s = -1e-4"),
    ),
    _c(
        "dt_longer_than_run",
        "values",
        "dt_s = 0.5 for a 0.2 s run",
        [S, "[integration] dt_s", "duration_s"],
        "0.5",
        edit(BASE, "dt_s = 1e-4", "dt_s = 0.5"),
    ),
    _c(
        "dt_longer_than_record",
        "values",
        "dt_s = 0.5 for a 0.09 s record",
        [S, "[integration] dt_s", "rec.AT2"],
        "0.5",
        edit(record_scene(), "dt_s = 1e-4", "dt_s = 0.5"),
        files={"rec.AT2": GOOD_AT2},
    ),
    _c(
        "record_run_absurdly_long",
        "values",
        "duration_s = 1e9 for a record (1e13 steps)",
        ["rec.AT2", "dt=0.0001"],
        "1000000000.0 s",
        record_scene(extra="duration_s = 1e9\n"),
        files={"rec.AT2": GOOD_AT2},
    ),
    _c(
        "dt_absurdly_small",
        "values",
        "dt_s = 1e-300 (5e299 steps)",
        [S, "[integration] dt_s"],
        "1e-300",
        edit(BASE, "dt_s = 1e-4", "dt_s = 1e-300"),
    ),
    _c(
        "nan_value",
        "values",
        "amplitude_m = nan",
        [S, "[excitation] amplitude_m"],
        "nan",
        edit(BASE, "amplitude_m = 0.002", "amplitude_m = nan"),
    ),
    _c(
        "inf_value",
        "values",
        "duration_s = inf",
        [S, "[excitation] duration_s"],
        "inf",
        edit(BASE, "duration_s = 0.2", "duration_s = inf"),
    ),
    _c(
        "damping_ratio_above_1",
        "values",
        "damping_ratio = 1.5",
        [S, "[building1] damping_ratio"],
        "1.5",
        edit(BASE, "damping_ratio = 0.0105", "damping_ratio = 1.5"),
    ),
    _c(
        "story_stiffness_scales_wrong_length",
        "values",
        "story_stiffness_scales = [1.0, 1.0] on a 3-story building",
        [S, "[building1] story_stiffness_scales"],
        ["[1.0, 1.0]", "one factor per story, 3 here"],
        edit(BASE, "damping_ratio = 0.0105", "damping_ratio = 0.0105\nstory_stiffness_scales = [1.0, 1.0]"),
    ),
    _c(
        "modal_damping_with_damping_ratio",
        "values",
        "modal_damping_ratios beside damping_ratio",
        [S, "[building1]"],
        ["modal_damping_ratios", "one form of damping"],
        edit(BASE, "damping_ratio = 0.0105", "damping_ratio = 0.0105\nmodal_damping_ratios = [0.01, 0.01, 0.01]"),
    ),
    _c(
        "modal_damping_ratio_above_1",
        "values",
        "modal_damping_ratios = [0.01, 1.2, 0.01]",
        [S, "[building1] modal_damping_ratios"],
        ["1.2", "[0, 1)"],
        edit(BASE, "damping_ratio = 0.0105", "modal_damping_ratios = [0.01, 1.2, 0.01]"),
    ),
    _c(
        "damping_modes_one_storey",
        "values",
        "damping_modes = [1, 5] on a one-storey building",
        [S, "[building2] damping_modes"],
        ["[1, 5]", "only mode 1"],
        edit(
            BASE,
            "masses_kg = [0.56, 0.56, 0.45]\n",
            "masses_kg = [0.56]\ndamping_modes = [1, 5]\n",
        ),
    ),
    _c(
        "negative_frequency",
        "values",
        "frequency_Hz = -6",
        [S, "[excitation] frequency_Hz"],
        "-6.0",
        edit(BASE, "frequency_Hz = 6.0", "frequency_Hz = -6"),
    ),
    _c(
        "unknown_law",
        "values",
        'law = "hertz-mindlin"',
        [S, "[contact] law"],
        "'hertz-mindlin'",
        edit(BASE, 'law = "classic"', 'law = "hertz-mindlin"'),
    ),
    _c(
        "unknown_scheme",
        "values",
        'scheme = "euler"',
        [S, "[integration] scheme"],
        "'euler'",
        edit(BASE, 'scheme = "event"', 'scheme = "euler"'),
    ),
    _c(
        "unknown_excitation_type",
        "values",
        'type = "sine"',
        [S, "[excitation] type"],
        "'sine'",
        edit(BASE, 'type = "harmonic"', 'type = "sine"'),
    ),
    _c("missing_section", "values", "no [contact] section", [S, "[contact]"], "missing", edit(BASE, CONTACT, "")),
    # ------------------------------------------------------------------ single-building scenes (issue 27)
    _c(
        "contact_without_building2",
        "values",
        "[contact] but no [building2]",
        [S, "[contact]", "[building2]"],
        "without",
        edit(BASE, BUILDING2, ""),
    ),
    _c(
        "single_building_contact_axis",
        "values",
        "one building, [sweep] ks_ratio",
        [S, "[sweep] ks_ratio"],
        "single-building",
        single_building(BASE),
    ),
    _c(
        "single_building_fits_building2",
        "values",
        "one building, [calibrate] fits stiffness_scale_b2",
        [S, "[calibrate] parameters.stiffness_scale_b2"],
        "single-building",
        single_building(table_scene().replace('b2f3 = "b2f3"', 'b2f2 = "b1f2"'), "stiffness_scale_b1 = [1.0]\n")
        + "\n[calibrate]\nparameters = { stiffness_scale_b2 = [0.9, 1.1] }\n",
    ),
    _c(
        "single_building_channel_b2",
        "values",
        "one building, an experiment channel on building 2",
        [S, "[experiment] channels.b2f3"],
        ["'b2f3'", "no building 2"],
        single_building(table_scene(), "stiffness_scale_b1 = [1.0]\n"),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "single_building_force_history",
        "values",
        "one building, [output] histories = ['force_f3']",
        [S, "[output] histories", "force_f3"],
        "no contact force",
        single_building(BASE, "stiffness_scale_b1 = [1.0]\n").replace(
            'path = "out.parquet"', 'path = "out.parquet"\nhistories = ["force_f3"]'
        ),
    ),
    _c(
        "cli_negative_threads",
        "values",
        "--threads -1",
        ["--threads"],
        "-1",
        argv=("{scene}", "--out", "{out}", "--threads", "-1"),
    ),
    # ------------------------------------------------------------------ sweep axes and grid size
    _c("empty_axis", "grid", "[sweep] r = []", [S, "[sweep] r"], "[]", edit(BASE, "r = [0.2, 0.6]", "r = []")),
    _c(
        "zero_length_range",
        "grid",
        "[sweep] r = {num = 0}",
        [S, "[sweep] r.num"],
        "0",
        edit(BASE, "r = [0.2, 0.6]", "r = {start = 0.0, stop = 1.0, num = 0}"),
    ),
    _c(
        "repeated_axis_values",
        "grid",
        "[sweep] ks_ratio = [1.0, 1.0]",
        [S, "[sweep] ks_ratio"],
        "repeated",
        edit(BASE, "ks_ratio = [0.1, 1.0]", "ks_ratio = [1.0, 1.0]"),
    ),
    _c(
        "huge_grid_unconfirmed",
        "grid",
        "2,502,500 runs without --yes",
        [S, "[sweep]", "max_runs"],
        "2,502,500",
        edit(
            edit(BASE, "ks_ratio = [0.1, 1.0]", "ks_ratio = {start = 0.1, stop = 10.0, num = 2500}"),
            "r = [0.2, 0.6]",
            "r = {start = 0.0, stop = 1.0, num = 1001}",
        ),
        sub=True,
    ),
    _c(
        "grid_over_max_runs",
        "grid",
        "4 runs with [execution] max_runs = 3",
        [S, "max_runs"],
        "4",
        BASE + "\n[execution]\nmax_runs = 3\n",
    ),
    _c(
        "grid_over_hard_limit",
        "grid",
        "10,000 x 10,000 grid points",
        [S, "[sweep]"],
        "100000000",
        edit(
            edit(BASE, "ks_ratio = [0.1, 1.0]", "ks_ratio = {start = 0.1, stop = 10.0, num = 10000}"),
            "r = [0.2, 0.6]",
            "r = {start = 0.0, stop = 1.0, num = 10000}",
        ),
    ),
    _c(
        "range_too_long",
        "grid",
        "one range of 10^9 values",
        [S, "[sweep] r.num"],
        "1,000,000,000",
        edit(BASE, "r = [0.2, 0.6]", "r = {start = 0.0, stop = 1.0, num = 1_000_000_000}"),
    ),
    _c(
        "log_range_through_zero",
        "grid",
        "log range from 0",
        [S, "[sweep] ks_ratio", "log spacing"],
        "0.0",
        edit(BASE, "ks_ratio = [0.1, 1.0]", "ks_ratio = {start = 0.0, stop = 10.0, num = 3, spacing = 'log'}"),
    ),
    _c(
        "both_stiffness_axes",
        "grid",
        "ks_ratio and ks_N_per_m both swept",
        [S, "[sweep]"],
        "ks_N_per_m",
        BASE.replace("[sweep]\n", "[sweep]\nks_N_per_m = [1000.0, 2000.0]\n"),
    ),
    # ------------------------------------------------------------------ records
    _c(
        "record_missing",
        "record",
        "record file does not exist",
        ["nowhere.AT2"],
        "No such file",
        record_scene("nowhere.AT2"),
        sub=True,
    ),
    _c(
        "record_is_a_folder",
        "record",
        "record path is a folder",
        ["rec.AT2"],
        "Is a directory",
        record_scene(),
        files={"rec.AT2": None},
    ),
    _c("record_empty", "record", "empty AT2 file", ["rec.AT2"], "0 line(s)", record_scene(), files={"rec.AT2": ""}),
    _c(
        "at2_no_npts",
        "record",
        "AT2 line 4 without NPTS",
        ["rec.AT2", "line 4"],
        "DT=   .0100 SEC",
        record_scene(),
        files={"rec.AT2": edit(GOOD_AT2, "NPTS=   10, ", "")},
    ),
    _c(
        "at2_npts_not_integer",
        "record",
        "NPTS= 10.5",
        ["rec.AT2", "line 4", "NPTS"],
        "'10.5'",
        record_scene(),
        files={"rec.AT2": edit(GOOD_AT2, "NPTS=   10", "NPTS=   10.5")},
    ),
    _c(
        "at2_dt_zero",
        "record",
        "DT= 0.0000",
        ["rec.AT2", "line 4", "DT"],
        "'0.0000'",
        record_scene(),
        files={"rec.AT2": edit(GOOD_AT2, "DT=   .0100", "DT=   0.0000")},
    ),
    _c(
        "at2_fewer_values_than_npts",
        "record",
        "NPTS= 12, 10 values",
        ["rec.AT2", "NPTS"],
        ["12", "10 values"],
        record_scene(),
        files={"rec.AT2": edit(GOOD_AT2, "NPTS=   10", "NPTS=   12")},
        sub=True,
    ),
    _c(
        "at2_more_values_than_npts",
        "record",
        "NPTS= 8, 10 values",
        ["rec.AT2", "line 6", "NPTS"],
        "-.2000000E-01",
        record_scene(),
        files={"rec.AT2": edit(GOOD_AT2, "NPTS=   10", "NPTS=    8")},
    ),
    _c(
        "at2_nan_value",
        "record",
        "NaN among the values",
        ["rec.AT2", "line 5"],
        "'NaN'",
        record_scene(),
        files={
            "rec.AT2": edit(
                GOOD_AT2, "  .3000000E-01  .2000000E-01  .1000000E-01\n -", "  NaN  .2000000E-01  .1000000E-01\n -"
            )
        },
    ),
    _c(
        "at2_text_value",
        "record",
        "a word among the values",
        ["rec.AT2", "line 6"],
        "'abc'",
        record_scene(),
        files={"rec.AT2": edit(GOOD_AT2, " -.3000000E-01", " abc")},
    ),
    _c(
        "at2_overflow_value",
        "record",
        "1e999 among the values",
        ["rec.AT2", "line 5"],
        "'1e999'",
        record_scene(),
        files={"rec.AT2": GOOD_AT2.replace("  .1000000E-01  .2000000E-01", "  1e999  .2000000E-01", 1)},
    ),
    _c(
        "at2_unknown_header_units",
        "record",
        "header: UNITS OF FT/S2",
        ["rec.AT2", "line 3"],
        "'FT/S2'",
        record_scene(),
        files={"rec.AT2": edit(GOOD_AT2, "UNITS OF G", "UNITS OF FT/S2")},
    ),
    _c(
        "at2_units_contradict_header",
        "record",
        'units = "gal" on an AT2 whose header says UNITS OF G',
        ["rec.AT2", "line 3"],
        ["units = 'gal'", "'UNITS OF G'"],
        record_scene(extra='units = "gal"\n'),
        files={"rec.AT2": GOOD_AT2},
    ),
    _c(
        "at2_header_names_two_units",
        "record",
        "header: IN G (1 G = 981 CM/S2)",
        ["rec.AT2", "line 3"],
        ["'CM/S2'", "'IN G'"],
        record_scene(),
        files={"rec.AT2": edit(GOOD_AT2, "IN UNITS OF G", "IN G (1 G = 981 CM/S2)")},
    ),
    _c(
        "at2_velocity_record",
        "record",
        "a VELOCITY .VT2 file named .AT2",
        ["rec.AT2", "line 3"],
        "VELOCITY",
        record_scene(),
        files={
            "rec.AT2": edit(GOOD_AT2, "ACCELERATION TIME SERIES IN UNITS OF G", "VELOCITY TIME SERIES IN UNITS OF CM/S")
        },
    ),
    _c(
        "record_unknown_units_key",
        "record",
        'units = "furlongs/s2" in [excitation]',
        [S, "[excitation] units"],
        "'furlongs/s2'",
        record_scene(extra='units = "furlongs/s2"\n'),
        files={"rec.AT2": GOOD_AT2},
    ),
    _c(
        "record_unknown_format_key",
        "record",
        'format = "mseed"',
        [S, "[excitation] format"],
        "'mseed'",
        record_scene(extra='format = "mseed"\n'),
        files={"rec.AT2": GOOD_AT2},
    ),
    _c(
        "record_pickle",
        "record",
        "record = 'rec.pkl' (a pickle)",
        ["rec.pkl"],
        "'.pkl'",
        record_scene("rec.pkl"),
        files={"rec.pkl": PICKLE},
    ),
    _c(
        "record_pickle_read_as_csv",
        "record",
        "a pickle with format = 'csv'",
        ["rec.pkl"],
        "binary data",
        record_scene("rec.pkl", 'format = "csv"\n'),
        files={"rec.pkl": PICKLE},
    ),
    _c(
        "record_url",
        "record",
        "record = 'http://example.com/r.AT2'",
        ["http:/example.com/r.AT2"],
        "No such file",
        record_scene("http://example.com/r.AT2"),
    ),
    _c(
        "csv_three_columns",
        "record",
        "CSV record row with 3 columns",
        ["rec.csv", "line 3"],
        "'0.01,0.1,9'",
        record_scene("rec.csv"),
        files={"rec.csv": edit(GOOD_CSV_RECORD, "0.01,0.1\n", "0.01,0.1,9\n")},
    ),
    _c(
        "csv_time_backwards",
        "record",
        "CSV time going back",
        ["rec.csv", "line 4", "strictly increasing"],
        "0.005",
        record_scene("rec.csv"),
        files={"rec.csv": edit(GOOD_CSV_RECORD, "0.02,0.2\n", "0.005,0.2\n")},
    ),
    _c(
        "csv_non_uniform_step",
        "record",
        "CSV time step 0.01 then 0.015",
        ["rec.csv", "line", "non-uniform"],
        "0.015",
        record_scene("rec.csv"),
        files={"rec.csv": edit(GOOD_CSV_RECORD, "0.09,0.0\n", "0.095,0.0\n")},
    ),
    _c(
        "csv_text_value",
        "record",
        "'n/a' in the acceleration column",
        ["rec.csv", "line 5"],
        "'n/a'",
        record_scene("rec.csv"),
        files={"rec.csv": edit(GOOD_CSV_RECORD, "0.03,0.0\n", "0.03,n/a\n")},
    ),
    _c(
        "csv_only_header",
        "record",
        "CSV record with only its header",
        ["rec.csv"],
        "found 0",
        record_scene("rec.csv"),
        files={"rec.csv": "t_s,acc_m_s2\n"},
    ),
    _c(
        "record_axis_one_bad",
        "record",
        "[sweep] record = [good, cut short]",
        ["short.AT2", "NPTS"],
        "found 5 values",
        edit(record_scene(), 'record = "rec.AT2"\n', "").replace(
            "[sweep]\n", '[sweep]\nrecord = ["rec.AT2", "short.AT2"]\n'
        ),
        files={"rec.AT2": GOOD_AT2, "short.AT2": GOOD_AT2.rsplit("\n", 2)[0] + "\n"},
    ),
    # ------------------------------------------------------------------ tracked tables
    _c(
        "table_missing",
        "table",
        "experiment table does not exist",
        ["nowhere.csv"],
        "not found",
        table_scene("nowhere.csv"),
    ),
    _c(
        "table_missing_time_column",
        "table",
        "time column named `time`",
        ["exp.csv", "'t_s'"],
        "time, b1f3, b2f3",
        table_scene(),
        files={"exp.csv": table_csv(header="time,b1f3,b2f3")},
        sub=True,
    ),
    _c(
        "table_unsorted_time",
        "table",
        "time 0.005 after 0.01",
        ["exp.csv", "'t_s'", "row 3"],
        "0.005",
        table_scene(),
        files={"exp.csv": table_csv(t={2: "0.005"})},
    ),
    _c(
        "table_duplicate_time",
        "table",
        "time 0.01 twice",
        ["exp.csv", "'t_s'", "row 3", "duplicate"],
        "0.01",
        table_scene(),
        files={"exp.csv": table_csv(t={2: "0.01"})},
    ),
    _c(
        "table_non_uniform",
        "table",
        "one step of 0.015 s",
        ["exp.csv", "'t_s'", "uniformly"],
        "0.015",
        table_scene(),
        files={"exp.csv": table_csv(t={i: f"{0.01 * i + 0.005:.3f}" for i in range(5, 21)})},
    ),
    _c(
        "table_nan",
        "table",
        "NaN in b1f3",
        ["exp.csv", "'b1f3'", "row 4"],
        "nan",
        table_scene(),
        files={"exp.csv": table_csv(b1={3: "NaN"})},
    ),
    _c(
        "table_inf",
        "table",
        "inf in b2f3",
        ["exp.csv", "'b2f3'", "row 6"],
        "inf",
        table_scene(),
        files={"exp.csv": table_csv(b2={5: "inf"})},
    ),
    _c(
        "table_text_in_numbers",
        "table",
        "'12,5' (decimal comma, quoted) in b1f3",
        ["exp.csv", "'b1f3'", "row 7"],
        "'12,5'",
        table_scene(),
        files={"exp.csv": table_csv(b1={6: '"12,5"'})},
    ),
    _c(
        "table_text_in_time",
        "table",
        "'0.0x' in t_s",
        ["exp.csv", "'t_s'", "row 2"],
        "'0.0x'",
        table_scene(),
        files={"exp.csv": table_csv(t={1: "0.0x"})},
    ),
    _c(
        "table_missing_mapped_column",
        "table",
        "channels maps b2f3, table has none",
        ["exp.csv", "'b2f3'"],
        "b2f3",
        table_scene(),
        files={"exp.csv": "t_s,b1f3\n" + "".join(f"{0.01 * i:.2f},0.1\n" for i in range(21))},
    ),
    _c(
        "table_header_only",
        "table",
        "table with a header and no rows",
        ["exp.csv", "'t_s'"],
        "has 0",
        table_scene(),
        files={"exp.csv": "t_s,b1f3,b2f3\n"},
    ),
    _c(
        "table_time_column_as_channel",
        "table",
        "channels maps the time column t_s to a floor",
        [S, "[experiment] channels.t_s"],
        "'t_s' is the time column",
        edit(
            table_scene(), 'channels = { b1f3 = "b1f3", b2f3 = "b2f3" }', 'channels = { t_s = "b1f3", b2f3 = "b2f3" }'
        ),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_all_zero_channel",
        "table",
        "channel b2f3 zero in every row",
        ["exp.csv", "column 'b2f3'"],
        "zero throughout",
        table_scene(),
        files={"exp.csv": table_csv(b2={i: "0.0" for i in range(21)})},
    ),
    _c(
        "table_constant_channel",
        "table",
        "channel b1f3 2.5 in every row",
        ["exp.csv", "column 'b1f3'"],
        "constant (2.5 mm throughout)",
        table_scene(),
        files={"exp.csv": table_csv(b1={i: "2.5" for i in range(21)})},
    ),
    _c(
        "table_repeated_column_name",
        "table",
        "header t_s,b1f3,b1f3 (b1f3 twice)",
        ["exp.csv", "'b1f3'"],
        "more than once",
        edit(table_scene(), 'channels = { b1f3 = "b1f3", b2f3 = "b2f3" }', 'channels = { b1f3 = "b1f3" }'),
        files={"exp.csv": table_csv(header="t_s,b1f3,b1f3")},
    ),
    _c(
        "table_empty_file",
        "table",
        "0-byte table",
        ["exp.csv"],
        "No columns to parse",
        table_scene(),
        files={"exp.csv": ""},
    ),
    _c(
        "table_one_row",
        "table",
        "table with one row",
        ["exp.csv", "'t_s'"],
        "has 1",
        table_scene(),
        files={"exp.csv": table_csv(rows=1)},
    ),
    _c(
        "table_wrong_units_key",
        "table",
        'units = "cm"',
        [S, "[experiment] units"],
        "'cm'",
        edit(table_scene(), 'units = "mm"', 'units = "cm"'),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_channel_to_no_floor",
        "table",
        "channel mapped to b1f4 (3 floors)",
        [S, "channels.b1f3"],
        "'b1f4'",
        edit(table_scene(), 'b1f3 = "b1f3"', 'b1f3 = "b1f4"'),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_no_overlap",
        "table",
        "table times 100 s .. 100.2 s",
        ["exp.csv", "0 sample"],
        "100",
        table_scene(),
        files={"exp.csv": table_csv(t={i: f"{100 + 0.01 * i:.2f}" for i in range(21)})},
    ),
    _c(
        "table_window_reversed",
        "table",
        "window_s = [0.2, 0.1]",
        [S, "[experiment] window_s"],
        "[0.2, 0.1]",
        table_scene() + "window_s = [0.2, 0.1]\n",
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_acc_units_unknown",
        "table",
        'acc_units = "cm/s2" (an acceleration channel mapped)',
        [S, "[experiment] acc_units"],
        "'cm/s2'",
        edit(table_scene(), 'b2f3 = "b2f3" }', 'b2f3 = "abs_acc_b2f3" }\nacc_units = "cm/s2"'),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_acc_channel_to_no_floor",
        "table",
        "acceleration channel mapped to abs_acc_b2f4 (3 floors)",
        [S, "channels.b2f3"],
        "'abs_acc_b2f4'",
        edit(table_scene(), 'b2f3 = "b2f3" }', 'b2f3 = "abs_acc_b2f4" }'),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_lowpass_above_nyquist",
        "table",
        "lowpass_Hz = 60 on a table sampled every 0.01 s (Nyquist 50 Hz)",
        [S, "[experiment] lowpass_Hz", "exp.csv"],
        ["60.0", "50 Hz"],
        edit(table_scene(), 'b2f3 = "b2f3" }', 'b2f3 = "abs_acc_b2f3" }\nlowpass_Hz = 60.0'),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_sensor_unknown_filter",
        "table",
        "sensor_filter = 'kalman' (an unknown accelerometer filter)",
        [S, "[experiment] sensor_filter"],
        ["'kalman'", "average"],
        edit(table_scene(), 'b2f3 = "b2f3" }', 'b2f3 = "abs_acc_b2f3" }\nsensor_filter = "kalman"'),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_sensor_negative_rate",
        "table",
        "sensor_rate_Hz = -1000 for an averaging accelerometer",
        [S, "[experiment] sensor_rate_Hz"],
        "-1000.0",
        edit(
            table_scene(),
            'b2f3 = "b2f3" }',
            'b2f3 = "abs_acc_b2f3" }\nsensor_filter = "average"\nsensor_rate_Hz = -1000',
        ),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_sensor_cutoff_above_nyquist",
        "table",
        "sensor_cutoff_Hz = 600 on a sensor sampling at 1000 Hz (Nyquist 500 Hz)",
        [S, "[experiment] sensor_cutoff_Hz"],
        ["600.0", "500 Hz"],
        edit(
            table_scene(),
            'b2f3 = "b2f3" }',
            'b2f3 = "abs_acc_b2f3" }\nsensor_filter = "butter"\nsensor_rate_Hz = 1000\nsensor_cutoff_Hz = 600',
        ),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_sensor_rate_not_a_multiple",
        "table",
        "sensor_rate_Hz = 1050 averaging onto a table sampled every 0.01 s (100 samples/s)",
        [S, "[experiment] sensor_rate_Hz", "exp.csv"],
        ["1050.0", "100 samples/s"],
        edit(
            table_scene(),
            'b2f3 = "b2f3" }',
            'b2f3 = "abs_acc_b2f3" }\nsensor_filter = "average"\nsensor_rate_Hz = 1050',
        ),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_sensor_without_acceleration",
        "table",
        "sensor_filter = 'average' with displacement channels only",
        [S, "[experiment] sensor_filter"],
        "'average'",
        table_scene() + 'sensor_filter = "average"\nsensor_rate_Hz = 1000\n',
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_lowpass_without_acceleration",
        "table",
        "lowpass_Hz = 20 with displacement channels only",
        [S, "[experiment] lowpass_Hz"],
        "20.0",
        table_scene() + "lowpass_Hz = 20.0\n",
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_weights_unmapped_column",
        "table",
        "weights = { b1f3 = 1.0, b3 = 1.0 }: b3 is not mapped",
        [S, "[experiment] weights.b3"],
        "'b3'",
        table_scene() + "weights = { b1f3 = 1.0, b3 = 1.0 }\n",
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_corrupt_parquet",
        "table",
        "text file named exp.parquet",
        ["exp.parquet"],
        "cannot read",
        table_scene("exp.parquet"),
        files={"exp.parquet": "t_s,b1f3,b2f3\n0,0,0\n"},
    ),
    _c(
        "table_parquet_text_column",
        "table",
        "Parquet b1f3 column of strings",
        ["exp.parquet", "'b1f3'", "row 1"],
        "'a'",
        table_scene("exp.parquet"),
        files={
            "exp.parquet": lambda: _parquet_bytes(
                {"t_s": [0.01 * i for i in range(21)], "b1f3": ["a"] * 21, "b2f3": [0.0] * 21}
            )
        },
    ),
    _c(
        "table_pickle",
        "table",
        "table = 'exp.pkl' (a pickle)",
        ["exp.pkl"],
        "'.pkl'",
        table_scene("exp.pkl"),
        files={"exp.pkl": PICKLE},
        sub=True,
    ),
    _c(
        "table_url",
        "table",
        "table = 'https://example.com/x.csv' (never fetched)",
        ["https:/example.com/x.csv"],
        "not found",
        table_scene("https://example.com/x.csv"),
    ),
    _c(
        "table_is_a_folder",
        "table",
        "table path is a folder",
        ["exp.csv"],
        "a folder",
        table_scene(),
        files={"exp.csv": None},
    ),
    # ------------------------------------------------------------------ videos: a scene's [experiment.video]
    _c(
        "scene_video_missing",
        "video",
        "[experiment.video] path does not exist",
        ["nowhere.mkv"],
        "not found",
        video_scene("nowhere.mkv"),
        sub=True,
    ),
    _c(
        "scene_video_url",
        "video",
        "[experiment.video] path = 'https://example.com/v.mkv'",
        ["https:/example.com/v.mkv"],
        "not found",
        video_scene("https://example.com/v.mkv"),
    ),
    _c("scene_video_empty", "video", "0-byte video", ["run.mkv"], "0 bytes", video_scene(), files={"run.mkv": b""}),
    _c(
        "scene_video_text",
        "video",
        "a text file named run.mkv",
        ["run.mkv"],
        "not a video",
        video_scene(),
        files={"run.mkv": b"this is not a video\n" * 50},
    ),
    _c(
        "scene_video_truncated",
        "video",
        "the first 2000 bytes of a video",
        ["run.mkv"],
        "no frames",
        video_scene(),
        files={"run.mkv": video_head(2000)},
    ),
    _c(
        "scene_video_folder",
        "video",
        "video path is a folder",
        ["run.mkv"],
        "not a file",
        video_scene(),
        files={"run.mkv": None},
    ),
    _c(
        "scene_video_units_m",
        "video",
        'units = "m" with a video',
        [S, "[experiment] units"],
        "'m'",
        edit(video_scene(), 'units = "mm"', 'units = "m"'),
        files={"run.mkv": rendered_video},
    ),
    _c(
        "scene_video_bad_reference",
        "video",
        "references name an unknown marker",
        [S, "[experiment.video] references"],
        "'table_middle'",
        edit(video_scene(), 'references = ["table_left", "table_right"]', 'references = ["table_middle"]'),
        files={"run.mkv": rendered_video},
    ),
    _c(
        "scene_video_negative_scale",
        "video",
        "mm_per_px = -5",
        [S, "[experiment.video] mm_per_px"],
        "-5.0",
        edit(video_scene(), "mm_per_px = 5.0", "mm_per_px = -5.0"),
        files={"run.mkv": rendered_video},
    ),
    # ------------------------------------------------------------------ videos: the track command
    _c(
        "track_missing",
        "video",
        "track a video that does not exist",
        ["nowhere.mkv"],
        "not found",
        None,
        argv=track("nowhere.mkv"),
    ),
    _c(
        "track_empty",
        "video",
        "track a 0-byte video",
        ["run.mkv"],
        "0 bytes",
        None,
        files={"run.mkv": b""},
        argv=track(),
    ),
    _c(
        "track_not_video",
        "video",
        "track random bytes named .mkv",
        ["run.mkv"],
        "not a video",
        None,
        files={"run.mkv": bytes(np.random.default_rng(8).integers(0, 256, 3000, dtype=np.uint8))},
        argv=track(),
        sub=True,
    ),
    _c(
        "track_truncated_header",
        "video",
        "track the first 2000 bytes of a video",
        ["run.mkv"],
        "no frames",
        None,
        files={"run.mkv": video_head(2000)},
        argv=track(),
    ),
    _c(
        "track_truncated_to_one_frame",
        "video",
        "track the first 5 % of a video (1 frame left)",
        ["run.mkv"],
        "1 of the 40 frames",
        None,
        files={"run.mkv": video_fraction(0.05)},
        argv=track(),
    ),
    _c(
        "track_truncated_mid_stream",
        "video",
        "track the first 60 % of a video (cut mid-stream)",
        ["run.mkv", "truncated"],
        "of the 40 frames",
        None,
        files={"run.mkv": video_fraction(0.6)},
        argv=track(),
    ),
    _c(
        "track_still_image",
        "video",
        "track a PNG still named .mkv",
        ["run.mkv"],
        "frame",
        None,
        files={"run.mkv": png_still},
        argv=track(),
    ),
    _c(
        "track_pickle",
        "video",
        "track a pickle named run.pkl",
        ["run.pkl"],
        "not a video",
        None,
        files={"run.pkl": PICKLE},
        argv=track("run.pkl"),
    ),
    _c(
        "track_bad_out_suffix",
        "video",
        "track --out tracked.txt",
        ["tracked.txt"],
        "(.txt)",
        None,
        files={"run.mkv": rendered_video},
        argv=track() + ("--out", "{dir}/tracked.txt"),
    ),
    _c(
        "track_scene_without_video",
        "video",
        "track --scene naming a scene with no [experiment.video]",
        [S],
        "no [experiment.video]",
        BASE,
        files={"run.mkv": rendered_video},
        argv=track() + ("--scene", "{scene}"),
    ),
]

# ----------------------------------------------------------------------------- issue 17
# unbounded reads, the output location, resuming, execution settings: appended as one block
NOTES = "my notes, not results\n"
LONG_NAME = "a" * 300 + ".parquet"
LONG_NAME_SHOWN = "a" * 40


def _not_ours_parquet() -> bytes:
    return _parquet_bytes({"x": [1.0, 2.0]})


def _nested(depth: int) -> str:
    return edit(BASE, "masses_kg = [1.7, 1.7, 1.6]", "masses_kg = " + "[" * depth + "1.7" + "]" * depth)


def _million_floors() -> str:
    return edit(BASE, "masses_kg = [1.7, 1.7, 1.6]", "masses_kg = [" + "1.7, " * 999_999 + "1.7]")


CASES += [
    # ------------------------------------------------------------------ scene files that are no files, or too much
    _c(
        "scene_is_dev_zero",
        "toml",
        "python -m pounding_sweep /dev/zero (endless)",
        ["/dev/zero"],
        "a character device, not a regular file",
        None,
        argv=("/dev/zero", "--out", "{out}"),
    ),
    _c(
        "scene_is_a_fifo",
        "toml",
        "the scene file is a named pipe (a reader waits forever)",
        [S],
        "a FIFO (named pipe), not a regular file",
        None,
        files={S: Fifo()},
    ),
    _c(
        "scene_too_large",
        "toml",
        "a 17 MiB scene file",
        [S],
        "larger than the 16 MiB a scene file may be",
        None,
        files={S: Sparse(17 * 2**20)},
    ),
    _c(
        "toml_nested_5000_deep",
        "toml",
        "masses_kg nested 5000 arrays deep (tomllib's recursion)",
        [S],
        "nested too deeply",
        _nested(5000),
    ),
    _c(
        "toml_nested_50_deep",
        "toml",
        "masses_kg nested 50 arrays deep",
        [S],
        "nested more than 8 levels deep",
        _nested(50),
    ),
    _c(
        "million_floors",
        "values",
        "masses_kg with 1,000,000 values (the model's matrices would need 7 TiB)",
        [S, "[building1] masses_kg"],
        "1,000,000 floors, more than the 1,000",
        _million_floors(),
    ),
    _c(
        "history_of_building_3",
        "values",
        'histories = ["disp_b3f1"]',
        [S, "disp_b3f1"],
        "there is no building 3",
        BASE + '\nhistories = ["disp_b3f1"]\n',
    ),
    _c(
        "channel_of_building_3",
        "table",
        "channels = { b1f3 = 'b3f1' }",
        [S, "[experiment] channels.b1f3"],
        "there is no building 3",
        BASE + TABLE_SECTION.format(table="exp.csv").replace('b1f3 = "b1f3"', 'b1f3 = "b3f1"'),
        files={"exp.csv": table_csv()},
    ),
    # ------------------------------------------------------------------ records that are no text, or no file
    _c(
        "record_symlink_loop",
        "record",
        "the record is a symlink to itself",
        ["rec.AT2"],
        "Too many levels of symbolic links",
        record_scene(),
        files={"rec.AT2": Symlink("rec.AT2")},
    ),
    _c(
        "record_is_dev_zero",
        "record",
        'record = "/dev/zero" (endless)',
        ["/dev/zero"],
        "a character device, not a regular file",
        record_scene("/dev/zero", 'format = "at2"\n'),
    ),
    _c(
        "record_is_a_fifo",
        "record",
        "the record is a named pipe",
        ["rec.AT2"],
        "a FIFO (named pipe), not a regular file",
        record_scene(),
        files={"rec.AT2": Fifo()},
        sub=True,
    ),
    _c(
        "record_too_large",
        "record",
        "a 300 MiB record",
        ["rec.AT2"],
        "larger than the 256 MiB a record file may be",
        record_scene(),
        files={"rec.AT2": Sparse(300 * 2**20)},
    ),
    _c(
        "record_utf16",
        "record",
        "an AT2 record saved as UTF-16",
        ["rec.AT2"],
        "UTF-16 text, not UTF-8 or ASCII",
        record_scene(),
        files={"rec.AT2": GOOD_AT2.encode("utf-16")},
    ),
    _c(
        "record_binary",
        "record",
        "a PNG image named rec.csv",
        ["rec.csv"],
        "binary data",
        record_scene("rec.csv"),
        files={"rec.csv": png_still},
    ),
    # ------------------------------------------------------------------ tables that are no text, or no file
    _c(
        "table_is_a_fifo",
        "table",
        "the experiment table is a named pipe",
        ["exp.csv"],
        "a FIFO (named pipe), not a regular file",
        table_scene(),
        files={"exp.csv": Fifo()},
    ),
    _c(
        "table_utf16",
        "table",
        "the experiment table saved as UTF-16",
        ["exp.csv"],
        "UTF-16 text",
        table_scene(),
        files={"exp.csv": table_csv().encode("utf-16")},
    ),
    _c(
        "table_too_large",
        "table",
        "a 2.5 GiB experiment table",
        ["exp.csv"],
        "larger than the 2 GiB an experiment table may be",
        table_scene(),
        files={"exp.csv": Sparse(5 * 2**29)},
    ),
    # ------------------------------------------------------------------ where the results go
    _c(
        "out_is_a_user_file_overwrite",
        "output",
        "--out notes.txt --overwrite (a user's text file)",
        ["notes.txt"],
        "is a file, not a results folder",
        files={"notes.txt": NOTES},
        argv=("{scene}", "--out", "{dir}/notes.txt", "--overwrite"),
        sub=True,
    ),
    _c(
        "output_path_is_a_user_file",
        "output",
        '[output] path = "notes.txt", run with --overwrite',
        ["notes.txt"],
        "is a file, not a results folder",
        edit(BASE, 'path = "out.parquet"', 'path = "notes.txt"'),
        files={"notes.txt": NOTES},
        argv=("{scene}", "--overwrite"),
    ),
    _c(
        "out_is_a_user_folder_overwrite",
        "output",
        "--out a folder of the user's (notes and a part-00000.parquet of their own) --overwrite",
        ["mine"],
        "not a pounding_sweep result folder (no _sweep.json",
        files={"mine/notes.txt": NOTES, "mine/part-00000.parquet": _not_ours_parquet},
        argv=("{scene}", "--out", "{dir}/mine", "--overwrite"),
    ),
    _c(
        "out_is_a_fifo",
        "output",
        "--out names a named pipe",
        ["pipe"],
        "not a folder (a FIFO (named pipe))",
        files={"pipe": Fifo()},
        argv=("{scene}", "--out", "{dir}/pipe"),
    ),
    _c(
        "out_in_proc",
        "output",
        "--out /proc/pounding_out.parquet",
        ["/proc/pounding_out.parquet"],
        "cannot create the results folder here",
        argv=("{scene}", "--out", "/proc/pounding_out.parquet"),
    ),
    _c(
        "out_name_too_long",
        "output",
        "--out a 300-character name",
        [LONG_NAME_SHOWN],
        "File name too long",
        argv=("{scene}", "--out", "{dir}/" + LONG_NAME),
    ),
    _c(
        "out_under_a_file",
        "output",
        "--out notes.txt/out.parquet (a file as folder)",
        ["notes.txt/out.parquet"],
        "Not a directory",
        files={"notes.txt": NOTES},
        argv=("{scene}", "--out", "{dir}/notes.txt/out.parquet"),
    ),
    _c(
        "best_file_is_the_users",
        "output",
        "out.best.parquet (where a scored sweep writes its best runs) is a user's file",
        ["out.best.parquet"],
        "is not a file this package wrote",
        table_scene(),
        files={"exp.csv": table_csv(), "out.best.parquet": NOTES},
    ),
    # ------------------------------------------------------------------ resuming from a folder that holds ...
    _c(
        "resume_manifest_empty",
        "resume",
        "... an empty _sweep.json (a full disk, a copy cut short)",
        ["out.parquet/_sweep.json"],
        "it is empty",
        RESUMABLE,
        files=result_folder({"_sweep.json": b""}),
        sub=True,
    ),
    _c(
        "resume_manifest_cut_short",
        "resume",
        "... half of _sweep.json",
        ["out.parquet/_sweep.json"],
        "cut short or not JSON",
        RESUMABLE,
        files=result_folder({"_sweep.json": result(RESUMABLE, "_sweep.json", lambda b: b[: len(b) // 2])}),
    ),
    _c(
        "resume_manifest_not_ours",
        "resume",
        "... a _sweep.json of something else",
        ["out.parquet/_sweep.json"],
        "not a pounding_sweep manifest",
        RESUMABLE,
        files=result_folder({"_sweep.json": '{"hello": "world"}'}),
    ),
    _c(
        "resume_part_cut_short",
        "resume",
        "... a part cut in half",
        ["out.parquet/part-00001.parquet"],
        "cannot be read as Parquet (cut short or damaged)",
        RESUMABLE,
        files=result_folder(
            {"part-00001.parquet": result(RESUMABLE, "part-00001.parquet", lambda b: b[: len(b) // 2])}
        ),
    ),
    _c(
        "resume_part_of_another_sweep",
        "resume",
        "... a part copied in from the same sweep at dt = 2e-4",
        ["out.parquet/part-00001.parquet", "[integration] dt_s"],
        "0.0002 there, 0.0001 now",
        RESUMABLE,
        files=result_folder({"part-00001.parquet": result(OTHER_DT, "part-00001.parquet")}),
    ),
    _c(
        "resume_part_not_ours",
        "resume",
        "... a Parquet file of the user's named part-00001.parquet",
        ["out.parquet/part-00001.parquet"],
        "not a part this package wrote",
        RESUMABLE,
        files=result_folder({"part-00001.parquet": _not_ours_parquet}),
    ),
    _c(
        "resume_part_beyond_the_grid",
        "resume",
        "... a third part in a sweep of two",
        ["out.parquet/part-00002.parquet"],
        "beyond the 2 parts of this sweep",
        RESUMABLE,
        files=result_folder({"part-00002.parquet": result(RESUMABLE, "part-00001.parquet")}),
    ),
    _c(
        "resume_another_sweep",
        "resume",
        "... the results of the same scene at dt = 2e-4",
        ["out.parquet", "[integration] dt_s"],
        "0.0002 there, 0.0001 now",
        RESUMABLE,
        files=result_folder(scene_text=OTHER_DT),
    ),
    # ------------------------------------------------------------------ how it runs
    # ------------------------------------------------------------------ raw sensor exports (import, issue 27)
    _c(
        "import_unknown_format",
        "table",
        "import of a two-column CSV record (not a sensor export)",
        ["ground.csv"],
        "not a sensor export this reader knows",
        None,
        {"ground.csv": GOOD_CSV_RECORD, "b1f1.csv": xsens_csv()},
        import_argv(),
    ),
    _c(
        "import_sensor_without_name",
        "table",
        "import ground.csv (NAME=FILE expected)",
        ["ground.csv"],
        "a sensor is NAME=FILE",
        None,
        XSENS_PAIR,
        ("import", "{dir}/ground.csv", "--out", "{dir}/imported"),
    ),
    _c(
        "import_reference_missing",
        "table",
        "import --reference table (no sensor of that name)",
        ["--reference table"],
        "no sensor of that name",
        None,
        XSENS_PAIR,
        import_argv("--reference", "table"),
    ),
    _c(
        "import_clock_repeats",
        "table",
        "an Xsens export whose SampleTimeFine repeats a row",
        ["b1f1.csv", "line 20"],
        "SampleTimeFine 2042736293 repeats the row before",
        None,
        {"ground.csv": xsens_csv(), "b1f1.csv": xsens_csv(ticks={10: "2042736293", 11: "2042736293"})},
        import_argv(),
    ),
    _c(
        "import_acc_not_a_number",
        "table",
        "an Xsens export with 'n/a' in Acc_X",
        ["b1f1.csv", "line 14", "column Acc_X"],
        "is not a finite number",
        None,
        {"ground.csv": xsens_csv(), "b1f1.csv": xsens_csv(acc_x={5: "n/a"})},
        import_argv(),
    ),
    _c(
        "import_quiet_window_outside",
        "table",
        "import --quiet 50,51 on 0.5 s of data",
        ["--quiet 50,51"],
        "holds 0 samples of the common span",
        None,
        XSENS_PAIR,
        import_argv("--quiet", "50,51", "--band", "1,10"),
    ),
    _c(
        "import_units_unknown",
        "table",
        "an Xsens export in mm/s^2 (gravity reads 9810)",
        ["b1f1.csv", "9810"],
        "their units are neither",
        None,
        {"ground.csv": xsens_csv(), "b1f1.csv": xsens_csv(gain=500.0, g=9810.0)},
        import_argv(),
    ),
    _c(
        "import_acc_absurd",
        "table",
        "an Xsens export with one Acc_X sample of 1e9 m/s^2",
        ["b1f1.csv", "line 14", "Acc_X = 1e+09"],
        "beyond 1e+06 m/s^2",
        None,
        {"ground.csv": xsens_csv(), "b1f1.csv": xsens_csv(acc_x={5: "1e9"})},
        import_argv(),
    ),
    _c(
        "import_line_cut_short",
        "table",
        "an Xsens export whose last line stops after 9 of its 11 fields",
        ["b1f1.csv", "line 72"],
        "9 of the header's 11 fields",
        None,
        {"ground.csv": xsens_csv(), "b1f1.csv": xsens_csv(tag="floor", gain=0.7).rstrip("\n").rsplit(",", 2)[0] + "\n"},
        import_argv(),
    ),
    _c(
        "import_same_file_twice",
        "table",
        "import ground=g.csv b1f1=g.csv (the table's file for a floor)",
        ["ground.csv", "sensor ground", "sensor b1f1"],
        "one file per sensor",
        None,
        XSENS_PAIR,
        ("import", "ground={dir}/ground.csv", "b1f1={dir}/ground.csv", "--out", "{dir}/imported"),
    ),
    _c(
        "import_same_samples",
        "table",
        "two sensors' files holding the same samples (a copy)",
        ["b1f1.csv", "sensor b1f1", "sensor ground"],
        "the same export twice",
        None,
        {"ground.csv": xsens_csv(), "b1f1.csv": xsens_csv()},
        import_argv(),
    ),
    _c(
        "import_axis_vertical",
        "table",
        "import --axis z on exports whose Z axis reads gravity",
        ["ground.csv", "--axis z", "Acc_Z", "9.810 m/s^2"],
        "the vertical one, not a shaking axis",
        None,
        XSENS_PAIR,
        import_argv("--axis", "z"),
    ),
    _c(
        "import_max_lag_negative",
        "table",
        "import --max-lag -1",
        ["--max-lag -1"],
        "a positive number of seconds",
        None,
        XSENS_PAIR,
        import_argv("--max-lag=-1"),
    ),
    _c(
        "import_band_above_nyquist",
        "table",
        "import --band 1,100 on 120 Hz sensors",
        ["--band 1,100", "60 Hz"],
        "above",
        None,
        XSENS_PAIR,
        import_argv("--band", "1,100"),
    ),
    _c(
        "import_out_not_ours",
        "table",
        "import --out a folder holding a user's notes",
        ["imported"],
        "exists and is not an earlier import's output",
        None,
        {**XSENS_PAIR, "imported/notes.txt": NOTES},
        import_argv(),
    ),
    _c(
        "table_time_in_us",
        "table",
        "experiment table whose time column is in microseconds",
        [S.replace("scene.toml", "exp.csv"), "column 't_s'"],
        ["steps by 10000 s", "is it in us?"],
        table_scene(),
        {"exp.csv": table_csv(t={i: f"{1e4 * i:.0f}" for i in range(21)})},
    ),
    _c(
        "identify_time_in_us",
        "table",
        "identify on a table whose time column is in microseconds",
        ["exp.csv", "column 't_s'"],
        ["steps by 10000 s", "in us it is 0.01 s"],
        None,
        {"exp.csv": table_csv(rows=40, t={i: f"{1e4 * i:.0f}" for i in range(40)})},
        ("identify", "{dir}/exp.csv"),
    ),
    _c(
        "identify_start_past_the_end",
        "table",
        "identify --start 200 on a 0.39 s table",
        ["exp.csv", "--start 200"],
        "leaves 0 samples of the table",
        None,
        {"exp.csv": table_csv(rows=40)},
        ("identify", "{dir}/exp.csv", "--start", "200"),
    ),
    _c(
        "experiment_noise_unmapped",
        "table",
        "[experiment] noise for a column that is not a channel",
        [S, "[experiment] noise.b9f9"],
        "'b9f9' is not a mapped channel",
        table_scene().replace("max_lag_s = 0.05", "max_lag_s = 0.05\nnoise = { b9f9 = 0.05 }"),
        {"exp.csv": table_csv()},
    ),
    _c(
        "experiment_noise_window_empty",
        "table",
        "[experiment] noise_window_s = [5, 6] beyond a 0.2 s table",
        ["[experiment] noise_window_s"],
        "holds 0 sample(s)",
        table_scene().replace("max_lag_s = 0.05", "max_lag_s = 0.05\nnoise_window_s = [5.0, 6.0]"),
        {"exp.csv": table_csv()},
    ),
    _c(
        "threads_100000",
        "execution",
        "--threads 100000",
        ["--threads"],
        "100000: more than 1,024",
        argv=("{scene}", "--out", "{out}", "--threads", "100000"),
        sub=True,
    ),
    _c(
        "workers_100000",
        "execution",
        "--workers 100000",
        ["--workers"],
        "100000: more than 1,024",
        argv=("{scene}", "--out", "{out}", "--workers", "100000"),
    ),
    _c(
        "scene_threads_100000",
        "execution",
        "[execution] threads = 100000",
        [S, "[execution] threads"],
        "100000: more than 1,024",
        BASE + "\n[execution]\nthreads = 100000\n",
    ),
    _c(
        "scene_dask_address_malformed",
        "execution",
        '[execution] dask_address = "not an address"',
        [S, "[execution] dask_address"],
        "not a scheduler address",
        BASE + '\n[execution]\nexecutor = "dask"\ndask_address = "not an address"\n',
    ),
    _c(
        "scene_dask_timeout_zero",
        "execution",
        "[execution] dask_timeout_s = 0",
        [S, "[execution] dask_timeout_s"],
        "must be > 0 s and finite",
        BASE + "\n[execution]\ndask_timeout_s = 0\n",
    ),
    _c(
        "dask_address_malformed",
        "execution",
        '--dask-address "not an address"',
        ["--dask-address"],
        "not a scheduler address",
        argv=("{scene}", "--out", "{out}", "--dask-address", "not an address"),
    ),
    _c(
        "dask_address_unreachable",
        "execution",
        "--dask-address tcp://127.0.0.1:9 (nothing listens there)",
        ["tcp://127.0.0.1:9"],
        "cannot reach a Dask scheduler",
        argv=("{scene}", "--out", "{out}", "--dask-address", "tcp://127.0.0.1:9"),
    ),
]

# ----------------------------------------------------------------------------- issue 25
# [calibrate] checked before the grid, the other commands' --out, plausibility, shared best tables


def _calibrated(params: str, extra: str = "", scene: str | None = None) -> str:
    """The table scene with a [calibrate] section fitting `params` (TOML inline table body)."""
    return (scene or table_scene()) + f"\n[calibrate]\nparameters = {{ {params} }}\n{extra}"


SCORED_RESUMABLE = table_scene() + "\n[execution]\nchunk_runs = 2\n"


@functools.lru_cache(maxsize=2)
def sweep_files(scene_text: str) -> dict[str, bytes]:
    """Every file a scored sweep of `scene_text` (its table: table_csv()) writes: the dataset folder's, as
    'out.parquet/<name>', and the best table beside it, 'out.best.parquet'."""
    import tempfile

    from pounding_sweep.scene import load_scene
    from pounding_sweep.sweep.run import run_scene

    with tempfile.TemporaryDirectory() as d:
        (Path(d) / "scene.toml").write_text(scene_text)
        (Path(d) / "exp.csv").write_text(table_csv())
        run_scene(load_scene(Path(d) / "scene.toml"), out_path=Path(d) / "out.parquet", threads=1)
        out = {f"out.parquet/{p.name}": p.read_bytes() for p in (Path(d) / "out.parquet").iterdir()}
        out["out.best.parquet"] = (Path(d) / "out.best.parquet").read_bytes()
        return out


#: what that sweep writes (4 runs in 2 parts)
SCORED_FILES = (
    "out.parquet/_sweep.json",
    "out.parquet/part-00000.parquet",
    "out.parquet/part-00001.parquet",
    "out.best.parquet",
)


def scored_results(**changes) -> dict:
    """The case's files for a scored sweep's results: exp.csv, out.parquet/, out.best.parquet (some replaced)."""
    files = {name: (lambda name=name: sweep_files(SCORED_RESUMABLE)[name]) for name in SCORED_FILES}
    files["exp.csv"] = table_csv()
    files.update(changes)
    return files


CASES += [
    # ------------------------------------------------------------------ [calibrate]: refused as the scene loads
    _c(
        "calibrate_amplitude_on_a_record",
        "calibrate",
        "[calibrate] fits amplitude_m on a record scene (it changes nothing)",
        [S, "[calibrate] parameters.amplitude_m"],
        "changes nothing here, the excitation is a record",
        _calibrated("amplitude_m = [0.001, 0.003]", scene=record_scene() + TABLE_SECTION.format(table="exp.csv")),
        files={"rec.AT2": GOOD_AT2, "exp.csv": table_csv()},
        sub=True,
    ),
    _c(
        "calibrate_kh_with_the_classic_law",
        "calibrate",
        "[calibrate] fits kh_N_per_m1_5 with law = classic (a linear law takes k_s)",
        [S, "[calibrate] parameters.kh_N_per_m1_5"],
        "changes nothing for [contact] law = 'classic'",
        _calibrated("kh_N_per_m1_5 = [1e5, 1e7]"),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_ks_with_kh_given",
        "calibrate",
        "[calibrate] fits ks_ratio while law hertzdamp takes [contact] kh_N_per_m1_5",
        [S, "[calibrate] parameters.ks_ratio"],
        "every law (hertzdamp) is Hertz-type and [contact] kh_N_per_m1_5 gives k_h",
        _calibrated(
            "ks_ratio = [0.1, 10.0]",
            scene=edit(
                edit(edit(table_scene(), "ks_ratio = 1.0\n", "kh_N_per_m1_5 = 2e5\n"), '"classic"', '"hertzdamp"'),
                "ks_ratio = [0.1, 1.0]\n",
                "",
            ),
        ),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_r_only_with_hertz",
        "calibrate",
        "[calibrate] fits only r with law = hertz (elastic: r changes nothing)",
        [S, "[calibrate] parameters.r"],
        "changes nothing for [contact] law = 'hertz'",
        _calibrated("r = [0.1, 1.0]", scene=edit(table_scene(), '"classic"', '"hertz"')),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_r_from_0_with_hertzdamp",
        "calibrate",
        "[calibrate] r = [0, 1] with law = hertzdamp (infinite damping at r = 0)",
        [S, "[calibrate] parameters.r"],
        "[0.0, 1.0]: law 'hertzdamp' has infinite damping at r = 0",
        _calibrated("r = [0.0, 1.0]", scene=edit(table_scene(), '"classic"', '"hertzdamp"')),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_story_beyond_the_building",
        "calibrate",
        "[calibrate] story_stiffness_scale_b1_s4 on a 3-story building",
        [S, "[calibrate] parameters.story_stiffness_scale_b1_s4"],
        "[building1] has 3 stories, no story 4",
        _calibrated("story_stiffness_scale_b1_s4 = [0.8, 1.2]"),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_mode_ratio_without_modal_damping",
        "calibrate",
        "[calibrate] modal_damping_ratio_b1_m1 where [building1] gives damping_ratio",
        [S, "[calibrate] parameters.modal_damping_ratio_b1_m1"],
        "gives no modal_damping_ratios to fit",
        _calibrated("modal_damping_ratio_b1_m1 = [0.0, 0.1]"),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_offset_of_an_unmapped_channel",
        "calibrate",
        "[calibrate] time_offset_s_b1f2 where [experiment] channels maps b1f3 and b2f3 only",
        [S, "[calibrate] parameters.time_offset_s_b1f2"],
        "maps no channel 'b1f2'",
        _calibrated("time_offset_s_b1f2 = [-0.01, 0.01]"),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_offset_of_every_channel_and_the_table",
        "calibrate",
        "[calibrate] time_offset_s with time_offset_s_b1f3 and time_offset_s_b2f3 (every channel): one shift twice",
        [S, "[calibrate] parameters.time_offset_s_b1f3"],
        "asks the data for one number twice",
        _calibrated(
            "time_offset_s = [-0.01, 0.01], time_offset_s_b1f3 = [-0.01, 0.01], time_offset_s_b2f3 = [-0.01, 0.01]"
        ),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_offset_beyond_half_a_period",
        "calibrate",
        "[calibrate] time_offset_s_b1f3 = [-0.5, 0.5] (building 1's first period is 0.235 s: the fit could lock a period off)",
        [S, "[calibrate] parameters.time_offset_s_b1f3"],
        "[-0.5, 0.5]: reaches beyond half the first period of building 1",
        _calibrated("time_offset_s_b1f3 = [-0.5, 0.5]"),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_start_from_missing",
        "calibrate",
        "[calibrate] start_from = 'modes.toml', no such file",
        [S, "[calibrate] start_from", "modes.toml"],
        "cannot read identify's modes",
        _calibrated("ks_ratio = [0.1, 10.0]", 'start_from = "modes.toml"\n'),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_start_from_not_modes",
        "calibrate",
        "[calibrate] start_from names a file whose frequencies_Hz is a word",
        [S, "[calibrate] start_from", "modes.toml"],
        "frequencies_Hz = 'x': a list of numbers",
        _calibrated("ks_ratio = [0.1, 10.0]", 'start_from = "modes.toml"\n'),
        files={"exp.csv": table_csv(), "modes.toml": "[building1]\nfrequencies_Hz = 'x'\n"},
    ),
    _c(
        "calibrate_global_points_1e9",
        "calibrate",
        "[calibrate] global_points = 1000000000",
        [S, "[calibrate] global_points"],
        "1,000,000,000: more than 4,096",
        _calibrated("ks_ratio = [0.1, 10.0]", "global_points = 1000000000\n"),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_profile_points_1e6",
        "calibrate",
        "[calibrate] profile_points = 1000000",
        [S, "[calibrate] profile_points"],
        "1,000,000: more than 200",
        _calibrated("ks_ratio = [0.1, 10.0]", "profile_points = 1000000\n"),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_noise_1e-300",
        "calibrate",
        "[calibrate] noise_m = 1e-300",
        [S, "[calibrate] noise_m"],
        "1e-300: the tracking noise in metres lies in [1e-09, 1]",
        _calibrated("ks_ratio = [0.1, 10.0]", "noise_m = 1e-300\n"),
        files={"exp.csv": table_csv()},
    ),
    # ------------------------------------------------------------------ [calibrate]: refused before the grid
    _c(
        "calibrate_offset_off_the_table",
        "calibrate",
        "[calibrate] time_offset_s = [-50, 50] on a 0.2 s table",
        [S, "[calibrate] parameters.time_offset_s", "exp.csv"],
        "at -50 s",
        _calibrated("ks_ratio = [0.1, 10.0], time_offset_s = [-50.0, 50.0]"),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_six_samples_no_noise_floor",
        "calibrate",
        "[calibrate] without noise_m, 6 samples in window_s = [0, 0.05]",
        [S, "[calibrate]", "b1f3"],
        "6 sample(s) in the scored window, fewer than the 11",
        _calibrated("ks_ratio = [0.1, 10.0]", scene=table_scene() + "window_s = [0.0, 0.05]\n"),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "calibrate_global_stage_too_large",
        "calibrate",
        "[calibrate] global_points = 4096 over 5 s runs (6.1 GiB of histories in one batch)",
        [S, "[calibrate] global_points"],
        "4,096: its runs are made as one batch and keep 6.1 GiB",
        _calibrated(
            "ks_ratio = [0.1, 10.0]",
            "global_points = 4096\n",
            edit(table_scene(), "duration_s = 0.2", "duration_s = 5.0"),
        ),
        files={"exp.csv": table_csv()},
    ),
    _c(
        "table_displacement_1e300_mm",
        "table",
        "a displacement of 1e300 mm in the experiment table",
        ["exp.csv", "'b1f3'"],
        "reaches 1e+300 mm",
        table_scene(),
        files={"exp.csv": table_csv(b1={5: "1e300"})},
    ),
    # ------------------------------------------------------------------ the other commands' outputs and options
    _c(
        "identify_out_is_the_scene",
        "commands",
        "identify exp.csv --scene scene.toml --out scene.toml (the scene itself)",
        ["scene.toml"],
        "exists and is not a file identify wrote",
        files={"exp.csv": table_csv()},
        argv=("identify", "{dir}/exp.csv", "--scene", "{scene}", "--out", "{scene}"),
        sub=True,
    ),
    _c(
        "track_out_is_a_users_file",
        "commands",
        "track ... --out notes.csv (a user's table)",
        ["notes.csv"],
        "exists and is not a file track wrote",
        files={"notes.csv": "t_s,mine\n0,1\n"},
        argv=track("run.mkv")[:-3] + ("--out", "{dir}/notes.csv", "--quiet"),
    ),
    _c(
        "gaps_out_is_a_users_file",
        "commands",
        "gaps scene.toml --out notes.txt (a user's file)",
        ["notes.txt"],
        "exists and is not a folder",
        files={"notes.txt": NOTES},
        argv=("gaps", "{scene}", "--out", "{dir}/notes.txt", "--quiet"),
    ),
    _c(
        "identify_modes_out_is_a_users_file",
        "commands",
        "identify exp.csv --modes-out notes.txt (a user's file)",
        ["notes.txt"],
        "exists and is not a file identify wrote",
        files={"exp.csv": table_csv(), "notes.txt": NOTES},
        argv=("identify", "{dir}/exp.csv", "--modes-out", "{dir}/notes.txt"),
    ),
    _c(
        "gaps_out_holds_a_users_csv",
        "commands",
        "gaps scene.toml --out study, a folder holding the user's required_gaps.csv",
        ["study/required_gaps.csv"],
        "exists and is not a file a gap study wrote",
        files={"study/required_gaps.csv": NOTES},
        argv=("gaps", "{scene}", "--out", "{dir}/study", "--quiet"),
    ),
    _c(
        "gaps_single_building",
        "commands",
        "gaps on a single-building scene",
        [S, "single-building"],
        "no [building2]",
        single_building(BASE, "stiffness_scale_b1 = [1.0]\n"),
        argv=("gaps", "{scene}", "--out", "{dir}/study", "--quiet"),
    ),
    _c(
        "gaps_length_scale_inf",
        "commands",
        "gaps --length-scale inf",
        ["--length-scale"],
        "must be a finite number > 0 (inf)",
        argv=("gaps", "{scene}", "--out", "{dir}/study", "--length-scale", "inf"),
    ),
    _c(
        "gaps_threads_negative",
        "commands",
        "gaps --threads -1",
        ["--threads"],
        "-1: must be >= 0",
        argv=("gaps", "{scene}", "--out", "{dir}/study", "--threads", "-1"),
    ),
    _c(
        "gaps_threads_100000",
        "commands",
        "gaps --threads 100000",
        ["--threads"],
        "100000: more than 1,024",
        argv=("gaps", "{scene}", "--out", "{dir}/study", "--threads", "100000"),
    ),
    _c(
        "gaps_relative_gap_inf",
        "commands",
        "gaps --relative-gaps 0,inf",
        ["--relative-gaps"],
        "expected finite numbers >= 0",
        argv=("gaps", "{scene}", "--out", "{dir}/study", "--relative-gaps", "0,inf"),
    ),
    _c(
        "gaps_relative_gap_twice",
        "commands",
        "gaps --relative-gaps 0,0,1 (a value twice: its row printed twice)",
        ["--relative-gaps '0,0,1'"],
        "0 given twice",
        argv=("gaps", "{scene}", "--out", "{dir}/study", "--relative-gaps=0,0,1"),
    ),
    _c(
        "plot_a_fifo",
        "commands",
        "plot pipe (a named pipe: a reader would wait for ever)",
        ["pipe"],
        "a FIFO (named pipe), not a result file or folder",
        files={"pipe": Fifo()},
        argv=("plot", "{dir}/pipe"),
    ),
    _c(
        "plot_out_inside_the_results",
        "commands",
        "plot out.parquet --out out.parquet/figures (PNGs among the parts)",
        ["out.parquet/figures"],
        "inside the result folder",
        SCORED_RESUMABLE,
        files=scored_results(),
        argv=("plot", "{out}", "--out", "{out}/figures"),
    ),
    _c(
        "plot_best_table_damaged",
        "commands",
        "plot out.parquet whose out.best.parquet is cut in half",
        ["out.best.parquet"],
        "cannot be read as a best-runs table (damaged)",
        SCORED_RESUMABLE,
        files=scored_results(**{"out.best.parquet": lambda: sweep_files(SCORED_RESUMABLE)["out.best.parquet"][:300]}),
        argv=("plot", "{out}"),
    ),
    _c(
        "best_table_of_another_result_folder",
        "output",
        "--out out (no suffix) beside out.parquet, whose best table out.best.parquet both would write",
        ["out.best.parquet"],
        "holds the best runs of the results in",
        SCORED_RESUMABLE,
        files=scored_results(),
        argv=("{scene}", "--out", "{dir}/out"),
    ),
]

# ----------------------------------------------------------------------------- risk studies (issue 29)

STOCHASTIC = (
    BASE.split("[excitation]")[0]
    + """\
[excitation]
type = "stochastic"
duration_s = 1.0
intensity = "sa"
scaling = "intensity"

[stochastic]
ground_frequency_Hz = 2.5
ground_damping = 0.6
s0_m2_per_s3 = 0.01

[integration]
dt_s = 0.005

[sweep]
seed = [0, 1, 2]
scale = [0.2, 0.4]

[risk]
intensities_g = [0.4]
"""
)
RISK = ("risk", "{scene}", "--out", "{dir}/study.risk")

CASES += [
    _c(
        "risk_single_building",
        "risk",
        "risk on a single-building scene",
        [S, "single-building"],
        "no [building2]",
        single_building(STOCHASTIC),
        argv=RISK,
    ),
    _c(
        "risk_without_intensity",
        "risk",
        "[risk] with [excitation] intensity = 'none'",
        [S, "[risk]"],
        "intensity",
        edit(edit(STOCHASTIC, 'intensity = "sa"', 'intensity = "none"'), 'scaling = "intensity"', 'scaling = "factor"'),
    ),
    _c(
        "risk_seed_fraction",
        "risk",
        "[sweep] seed = [0, 1.5]",
        [S, "[sweep] seed"],
        "1.5",
        edit(STOCHASTIC, "seed = [0, 1, 2]", "seed = [0, 1.5]"),
    ),
    _c(
        "risk_stochastic_section_missing",
        "risk",
        "type = 'stochastic' without a [stochastic] section",
        [S, "[excitation] type"],
        "[stochastic]",
        STOCHASTIC.split("[stochastic]")[0] + "[integration]" + STOCHASTIC.split("[integration]")[1],
    ),
    _c(
        "risk_intensity_not_a_level",
        "risk",
        "[risk] intensities_g = [0.3] with [sweep] scale = [0.2, 0.4]",
        [S, "[risk] intensities_g"],
        "0.3",
        edit(STOCHASTIC, "intensities_g = [0.4]", "intensities_g = [0.3]"),
        argv=RISK,
    ),
    _c(
        "risk_gap_axis",
        "risk",
        "[sweep] gap_m in a risk scene",
        [S, "[sweep] gap_m"],
        "sets the gaps itself",
        edit(STOCHASTIC, "scale = [0.2, 0.4]", "scale = [0.2, 0.4]\ngap_m = [0.1, 0.2]"),
        argv=RISK,
    ),
    _c(
        "risk_targets_repeated",
        "risk",
        "[risk] targets = [0.1, 0.1]",
        [S, "[risk] targets = [0.1, 0.1]"],
        "repeated values",
        edit(STOCHASTIC, "intensities_g = [0.4]", "intensities_g = [0.4]\ntargets = [0.1, 0.1]"),
        argv=RISK,
    ),
    _c(
        "risk_hazard_missing",
        "risk",
        "[risk] hazard = 'nowhere.csv' (no such file)",
        ["nowhere.csv"],
        "hazard table",
        edit(STOCHASTIC, "intensities_g = [0.4]", 'intensities_g = [0.4]\nhazard = "nowhere.csv"'),
        argv=RISK,
    ),
    _c(
        "risk_hazard_increasing",
        "risk",
        "a hazard table whose rate grows with the intensity",
        ["haz.csv"],
        "must decrease",
        edit(STOCHASTIC, "intensities_g = [0.4]", 'intensities_g = [0.4]\nhazard = "haz.csv"'),
        files={"haz.csv": "intensity_g,annual_rate\n0.1,0.01\n0.2,0.02\n"},
        argv=RISK,
    ),
    _c(
        "risk_subcommand_without_risk",
        "risk",
        "`risk` on a scene without a [risk] section",
        [S],
        "no [risk] section",
        argv=RISK,
        sub=True,
    ),
    _c(
        "risk_out_is_a_file",
        "risk",
        "`risk --out` naming a file",
        ["scene.toml"],
        "not a risk study folder",
        STOCHASTIC,
        argv=("risk", "{scene}", "--out", "{scene}"),
    ),
    _c(
        "risk_sweeps_contact",
        "risk",
        "a risk scene sweeping r (its contact runs take [contact]'s)",
        [S, "[sweep] r"],
        "ensemble",
        edit(STOCHASTIC, "scale = [0.2, 0.4]", "scale = [0.2, 0.4]\nr = [0.2, 0.4]"),
        argv=RISK,
    ),
]

#: inputs that should be refused but are not yet: each is run and expected to fail its check
#: (strict xfail in the test), so fixing the gap shows up. The reason says what is missing.
KNOWN_GAPS: dict = {}  # none left: a video cut mid-stream is now refused (VideoReader._check_complete)


# ----------------------------------------------------------------------------- running a case


@dataclass
class Outcome:
    code: int
    stdout: str
    stderr: str
    left_behind: list[str]  # files or folders that were not there before the run

    def message(self, case_dir: Path) -> str:
        """stderr with the case folder written as CASE (the outcome table's form)."""
        return normalise(self.stderr, case_dir)


def normalise(text: str, case_dir: Path) -> str:
    return text.replace(str(case_dir), "CASE").rstrip("\n")


def materialise(case: Case, case_dir: Path) -> None:
    """Write the case's scene and files into an empty folder."""
    case_dir.mkdir(parents=True, exist_ok=True)
    if case.scene is not None:
        data = case.scene if isinstance(case.scene, bytes) else case.scene.encode()
        (case_dir / "scene.toml").write_bytes(data)
    for name, content in case.files.items():
        p = case_dir / name
        p.parent.mkdir(parents=True, exist_ok=True)
        if content is None:
            p.mkdir()
            continue
        if isinstance(content, Symlink):
            p.symlink_to(content.target)
            continue
        if isinstance(content, Fifo):
            os.mkfifo(p)
            continue
        if isinstance(content, Sparse):
            with open(p, "wb") as f:
                f.truncate(content.size)
            continue
        if callable(content):
            content = content()
        p.write_bytes(content if isinstance(content, bytes) else content.encode())


def argv_of(case: Case, case_dir: Path) -> list[str]:
    subs = {"{dir}": str(case_dir), "{scene}": str(case_dir / "scene.toml"), "{out}": str(case_dir / "out.parquet")}
    out = []
    for a in case.argv:
        for k, v in subs.items():
            a = a.replace(k, v)
        out.append(a)
    return out


def snapshot(case_dir: Path) -> set[str]:
    return {str(p.relative_to(case_dir)) for p in case_dir.rglob("*")}


def run_in_process(case: Case, case_dir: Path) -> Outcome:
    """`pounding_sweep.cli.run(argv)` in this process, as the real command would see it: NumPy's
    default error handling, warnings shown as stderr lines, an escaping exception as a traceback."""
    from pounding_sweep.cli.run import main

    before = snapshot(case_dir)
    out, err = io.StringIO(), io.StringIO()
    with (
        contextlib.redirect_stdout(out),
        contextlib.redirect_stderr(err),
        np.errstate(divide="warn", over="warn", under="ignore", invalid="warn"),
        warnings.catch_warnings(record=True) as caught,
    ):
        warnings.simplefilter("default")
        try:
            code = main(argv_of(case, case_dir))
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else 1
        except BaseException:  # noqa: BLE001 - what the real command would print before dying
            traceback.print_exc(file=err)
            code = 1
    stderr = err.getvalue() + "".join(f"{w.filename}:{w.lineno}: {w.category.__name__}: {w.message}\n" for w in caught)
    return Outcome(code, out.getvalue(), stderr, sorted(snapshot(case_dir) - before))


def run_subprocess(case: Case, case_dir: Path, timeout: float = 300) -> Outcome:
    """The real command line: `python -m pounding_sweep ...` in a fresh process."""
    before = snapshot(case_dir)
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST")}
    p = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", *argv_of(case, case_dir)],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=timeout,
        env=env,
    )
    return Outcome(p.returncode, p.stdout, p.stderr, sorted(snapshot(case_dir) - before))


def problems(case: Case, outcome: Outcome, case_dir: Path) -> list[str]:
    """Every way the outcome breaks the bad-input contract (empty: the case passes)."""
    bad = []
    if outcome.code != EXIT_BAD_INPUT:
        bad.append(f"exit status {outcome.code}, not {EXIT_BAD_INPUT}")
    lines = outcome.stderr.splitlines()
    if "Traceback" in outcome.stderr:
        bad.append("a traceback")
    if len(lines) != 1 or not lines[0].startswith("error: "):
        bad.append(f"stderr is {len(lines)} line(s), not one 'error: ...' line")
    msg = outcome.stderr
    for frag in case.where + case.value:
        if frag not in msg:
            bad.append(f"message lacks {frag!r}")
    if outcome.left_behind:
        bad.append(f"left behind: {', '.join(outcome.left_behind)}")
    given = given_names(case)  # a case may bring a result folder of its own (the resume cases)
    made = [
        p
        for p in [case_dir / "out.parquet", *case_dir.rglob("*.tmp*"), *case_dir.rglob("part-*")]
        if (p.exists() or p.is_symlink()) and str(p.relative_to(case_dir)) not in given
    ]
    if made:
        bad.append("an output, part or temporary file exists")
    return bad


def given_names(case: Case) -> set[str]:
    """The files and folders a case's own inputs put in its folder (names relative to it)."""
    names = set()
    for name in case.files:
        parts = Path(name).parts
        names.update(str(Path(*parts[: i + 1])) for i in range(len(parts)))
    return names


def fresh_dir(root: Path, case: Case) -> Path:
    d = (root / case.id).resolve()
    if d.exists():
        shutil.rmtree(d)
    materialise(case, d)
    return d
