"""Parquet output: one row per run, units in column names, the scene and versions in the
file metadata, written to a temporary name and renamed only when complete.

A sweep's result is a Parquet dataset: a folder of parts `part-00000.parquet`, ... (one per chunk
of the grid, in run_id order), which pandas, pyarrow, polars and DuckDB read as one table, plus
`_sweep.json` (the config hash, package version and chunking, for resuming). Names starting with
'_' or '.' (the manifest, parts being written) are skipped by those readers."""

from __future__ import annotations

import errno
import fnmatch
import json
import os
import platform
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pounding_sweep import __version__
from pounding_sweep.engine import layout as L
from pounding_sweep.errors import OutputError
from pounding_sweep.scene.parameters import PARAMETERS

META_KEY = b"pounding_sweep"

#: what the non-obvious columns mean (stored in the metadata as well)
COLUMN_DOCS = {
    "run_id": "index of the run in the grid (last sweep axis fastest)",
    **{p.name: p.doc for p in PARAMETERS if p.name != "law"},  # the parameters' own (scene/parameters.py)
    "intensity_g": "the run's ground-motion intensity ([excitation] intensity: PGA or Sa(T, 5 %), metadata "
    "'intensity'), as run [g]",
    "contact_law": "the run's pounding law: classic, no_tension (eq. 8), hertz, hertzdamp, jankowski",
    "contact_damping_ratio": "xi from r by the law's relation: eq. 10 (classic, no_tension), Jankowski 2006 [-]",
    "hertzdamp_a": "hertzdamp: normalised damping a (F = k_h delta^1.5 (1 + a delta_dot / v0)) from r [-]",
    "r_single_impact": "restitution a single free impact returns with this law and damping (r's meaning) [-]",
    "steps_per_contact_period": "min over pairs of 2 pi sqrt(m_eff/k) / dt, k = k_s or 1.5 k_h sqrt(delta_ref) [-]",
    "dt_s": "dt = 'auto': the time step chosen for this run [s]",
    "dt_error_estimate": "dt = 'auto': Richardson estimate of the run's relative error at that dt [-]",
    "peak_disp_b*f*_m": "largest |displacement| of building b, floor f relative to the table [m]",
    "peak_disp_time_b*f*_s": "time of that peak [s]",
    "peak_abs_acc_b*f*_m_s2": "largest |absolute acceleration| (relative + table) [m/s^2]",
    "peak_drift_ratio_b*s*": "that drift over the story's height (story_height_m) [-]",
    "peak_drift_b*s*_m": "largest |interstory drift| of building b, story s (floor s minus floor s - 1; story 1: floor 1) [m]",
    "peak_force_f*_N": "largest pounding force at floor pair f, positive in compression [N]",
    "min_force_f*_N": "most negative (tensile) contact force of the classic law [N]",
    "impacts_f*": "number of contact phases (penetration > 0; the paper's scheme: at its contact-free trial) [-]",
    "contact_time_f*_s": "total time with penetration > 0 (the paper's scheme: at its contact-free trial) [s], resolution dt",
    "compression_time_f*_s": "total time with contact force > 0 [s], resolution dt",
    "compression_phases_f*": "number of phases with contact force > 0 [-]",
    "median_compression_phase_f*_s": "median duration of those phases [s], resolution dt",
    "max_penetration_f*_m": "largest penetration u1 - u2 - d [m]",
    "peak_force_time_f*_s": "time of the peak force [s]",
    "closest_approach_f*_m": "least gap - (u1 - u2) of floor pair f over the run (the gap at rest minus the largest "
    "relative displacement toward each other); < 0: the floors overlapped by that much [m]",
    "closest_approach_time_f*_s": "time of the closest approach [s]",
    "unsettled_steps": "steps whose contact solve did not settle (Newton stalled, events chattered) [-]",
    "max_contact_iterations": "most active-set (or Newton) iterations, or event scheme: contact events, any step needed [-]",
    "steps": "time steps completed [-]",
    "status": "'ok' or '+'-joined flags: diverged, contact_unsettled, contact_underresolved, energy_residual, unscored, median_truncated, dt_tolerance_not_met, grazing_impact",
    "input_energy_J": "work of the table motion on the structure, relative coordinates [J]",
    "input_work_abs_J": "sum of |input work increments|, the scale of the energy residual [J]",
    "kinetic_energy_end_J": "kinetic energy at the end (relative velocities) [J]",
    "strain_energy_end_J": "strain energy of the frames at the end [J]",
    "structural_damping_energy_J": "energy dissipated by Rayleigh damping [J]",
    "contact_damping_energy_J": "work of the contact dashpots, plus spring energy dropped at a no-tension release [J]",
    "contact_spring_energy_end_J": "energy stored in contact springs at the end (k_s d^2 / 2; Hertz: k_h d^2.5 / 2.5) [J]",
    "energy_residual_J": "input - all of the above: contact-spring work the switching (or, Hertz laws, the steps' "
    "quadrature) did not store (< 0: made) [J]",
    "run_time_s": "wall time of this run in the kernel [s]",
}

INT_COLUMNS = ("impacts_f", "compression_phases_f", "unsettled_steps", "max_contact_iterations", "steps")


def status_words(codes: np.ndarray) -> list[str]:
    """Status bit field -> 'ok' or the '+'-joined flag words."""
    out = []
    for c in codes.astype(np.int64):
        words = [w for bit, w in L.STATUS_WORDS.items() if c & bit]
        out.append("+".join(words) if words else "ok")
    return out


def arrow_array(values) -> pa.Array:
    """A NumPy column (float, int, bool, or objects/strings with None for missing) as an Arrow array.

    Built from the NumPy buffers: pa.array() imports pandas on its first call (to check for a
    Series; apache/arrow#34994), which cost a metrics-only sweep half a second of start-up."""
    if isinstance(values, pa.Array):  # built already (an integer column with nulls: metrics_table)
        return values
    v = np.asarray(values)
    n = v.size
    if v.dtype.kind == "f":
        return pa.Array.from_buffers(pa.float64(), n, [None, pa.py_buffer(np.ascontiguousarray(v, np.float64))])
    if v.dtype.kind in "iu":
        return pa.Array.from_buffers(pa.int64(), n, [None, pa.py_buffer(np.ascontiguousarray(v, np.int64))])
    if v.dtype.kind == "b":
        return pa.Array.from_buffers(pa.bool_(), n, [None, pa.py_buffer(np.packbits(v, bitorder="little"))])
    items = v.tolist()
    valid = np.array([x is not None for x in items], dtype=bool)
    enc = [str(x).encode() if x is not None else b"" for x in items]
    offsets = np.zeros(n + 1, dtype=np.int32)
    np.cumsum([len(e) for e in enc], out=offsets[1:])
    validity = None if valid.all() else pa.py_buffer(np.packbits(valid, bitorder="little"))
    return pa.Array.from_buffers(
        pa.string(), n, [validity, pa.py_buffer(offsets), pa.py_buffer(b"".join(enc))], null_count=int(n - valid.sum())
    )


def numpy_column(table: pa.Table, name: str) -> np.ndarray:
    """A float64 or int64 column of a table as float64 NumPy (nulls -> NaN), read from its buffers
    (Array.to_numpy imports pandas: see arrow_array)."""
    parts = []
    for chunk in table.column(name).chunks:
        kind = {pa.float64(): np.float64, pa.int64(): np.int64}.get(chunk.type)
        if kind is None:
            raise TypeError(f"column {name!r}: {chunk.type} is not float64 or int64")
        x = np.frombuffer(chunk.buffers()[1], dtype=kind, count=len(chunk), offset=chunk.offset * 8).astype(np.float64)
        if chunk.null_count:
            x[np.array(chunk.is_null().to_pylist(), dtype=bool)] = np.nan
        parts.append(x)
    return np.concatenate(parts) if parts else np.zeros(0)


def arrow_table(cols: dict) -> pa.Table:
    """Arrow table of named NumPy columns (see arrow_array)."""
    return pa.Table.from_arrays([arrow_array(v) for v in cols.values()], names=list(cols))


def metrics_table(
    params: dict[str, np.ndarray],
    metric_names: list[str],
    metrics: np.ndarray,
    run_time: np.ndarray,
    extra: dict[str, np.ndarray] | None = None,
) -> pa.Table:
    """Arrow table of a chunk: parameters, metrics, scores (extra), status and run time."""
    cols: dict[str, np.ndarray] = dict(params)
    for i, name in enumerate(metric_names):
        if name == "status_code":
            continue
        col = metrics[:, i]
        cols[name] = int_column(col) if name.startswith(INT_COLUMNS) else col
    cols.update(extra or {})
    cols["status"] = np.array(status_words(metrics[:, metric_names.index("status_code")]), dtype=object)
    cols["run_time_s"] = run_time
    return arrow_table(cols)


def int_column(col: np.ndarray):
    """A count column (float64 in the metric row) as int64; a NaN (a metric group left out: not computed) as a
    null, so the column keeps its int64 type and a reader sees a missing value, never a number."""
    missing = np.isnan(col)
    if not missing.any():
        return col.astype(np.int64)
    ints = np.where(missing, 0, col).astype(np.int64)
    valid = pa.py_buffer(np.packbits(~missing, bitorder="little"))
    return pa.Array.from_buffers(pa.int64(), ints.size, [valid, pa.py_buffer(ints)], null_count=int(missing.sum()))


#: the status flags a metric group sets (engine/layout.py: left out, the group's flag is never set)
GROUP_FLAGS = {"energy": "energy_residual", "phases": "median_truncated"}


def column_docs(left_out: list[str], groups_left_out: list[str], key: str) -> dict[str, str]:
    """COLUMN_DOCS for a sweep that left metric groups out: a column of theirs (`left_out`, names) described as not
    computed, and the status flags they would set named as not checked."""
    out = dict(COLUMN_DOCS)
    for pattern, doc in COLUMN_DOCS.items():
        if any(fnmatch.fnmatchcase(c, pattern) for c in left_out):
            out[pattern] = (
                f"not computed: {key} leaves out its group (NaN or null in every row); computed, it is: {doc}"
            )
    flags = [GROUP_FLAGS[g] for g in groups_left_out if g in GROUP_FLAGS]
    if flags:
        out["status"] += f"; not checked here: {', '.join(flags)} ({key} leaves out their groups)"
    return out


def versions() -> dict[str, str]:
    """The package's and its numerical libraries' versions: every file the package writes says what made it."""
    import numba
    import scipy

    return {
        "package": "pounding_sweep",
        "version": __version__,
        "numba_version": numba.__version__,
        "numpy_version": np.__version__,
        "scipy_version": scipy.__version__,
        "pyarrow_version": pa.__version__,
        "python_version": platform.python_version(),
    }


def file_metadata(scene, extra: dict, columns: dict[str, str] | None = None) -> dict[bytes, bytes]:
    """Key-value metadata: scene TOML, canonical config and hash, versions, units, model facts; `columns`: what
    each column means (default COLUMN_DOCS; a sweep leaving metric groups out passes column_docs)."""
    info = {
        **versions(),
        "scene_name": scene.name,
        "scene_file": str(Path(scene.source).resolve()),
        "config_hash": scene.config_hash(),
        "config": scene.canonical(),
        "units": "SI: m, kg, s, N; unit suffix in each column name",
        "columns": COLUMN_DOCS if columns is None else columns,
        **extra,
    }
    return {
        META_KEY: json.dumps(info, default=str).encode(),
        b"scene_toml": scene.toml_text.encode(),
        b"config_hash": info["config_hash"].encode(),
    }


def read_metadata(path: str | Path) -> dict:
    """The pounding_sweep metadata of a result file or dataset folder, as a dict."""
    return json.loads(read_schema(path).metadata[META_KEY])


def meta_warnings(metadata: dict[bytes, bytes]) -> list[str]:
    """The warnings stored in metadata made by file_metadata."""
    return list(json.loads(metadata[META_KEY]).get("warnings", []))


def store_warnings(folder: Path, messages: list[str]) -> None:
    """Put a sweep's warnings into the metadata of its first part (the one read_metadata reads): the
    parts carry the warnings known before the runs; those found from the results (no run made contact)
    come after every part is written. The part is rewritten under a temporary name and renamed."""
    parts = part_files(folder)
    if not parts or part_index(parts[0]) != 0:
        return
    table = pq.read_table(parts[0])
    md = dict(table.schema.metadata or {})
    if META_KEY not in md:
        return
    info = json.loads(md[META_KEY])
    if info.get("warnings") == list(messages):
        return
    info["warnings"] = list(messages)
    md[META_KEY] = json.dumps(info, default=str).encode()
    write_part(folder, 0, table, md)


def read_schema(path: str | Path) -> pa.Schema:
    """Schema (with the key-value metadata) of a result file, or of a dataset folder's first part."""
    p = Path(path)
    if p.is_dir():
        parts = part_files(p)
        if not parts:
            raise FileNotFoundError(f"{p}: no result parts (part-*.parquet) in this folder")
        p = parts[0]
    schema = pq.read_schema(p)
    if not schema.metadata or META_KEY not in schema.metadata:
        raise KeyError(f"{p}: not a pounding_sweep result (no '{META_KEY.decode()}' metadata)")
    return schema


# ----------------------------------------------------------------------------- dataset parts

PART_NAME = "part-{:05d}.parquet"
MANIFEST = "_sweep.json"
_PART = re.compile(r"part-(\d{5,})\.parquet")
#: hidden names only a sweep writes in its folders: parts and manifests being written, the folder's lock
_OURS_HIDDEN = re.compile(r"\.part-\d{5,}\.parquet(\.\d+)?\.tmp|\._sweep\.json(\.\d+)?\.tmp|\._sweep\.lock")


def part_files(folder: str | Path) -> list[Path]:
    """The finished parts of a dataset folder (named as this package names them), in order."""
    folder = Path(folder)
    try:
        names = sorted(p.name for p in folder.iterdir() if _PART.fullmatch(p.name))
    except (FileNotFoundError, NotADirectoryError):
        return []
    return [folder / n for n in names]


def part_index(path: Path) -> int:
    return int(_PART.fullmatch(path.name).group(1))


def is_own_temporary(name: str) -> bool:
    """A hidden file a sweep writes while it runs (a part or manifest being written, the lock)."""
    return _OURS_HIDDEN.fullmatch(name) is not None


def _cannot_write(path: Path, e: OSError) -> OutputError:
    what = e.strerror or str(e)
    hint = " (free some space, then run the same command again to resume)" if e.errno in _FULL else ""
    return OutputError(f"{path}: cannot write ({what}){hint}")


_FULL = {errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)}


def _discard(path: Path) -> None:
    try:
        path.unlink(missing_ok=True)
    except OSError:  # a read-only place, where nothing was written either
        pass


def _fsync_dir(folder: Path) -> None:
    """Make a rename in `folder` durable (where the platform can)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def write_table_atomic(path: Path, table: pa.Table, metadata: dict[bytes, bytes], before_rename=None) -> Path:
    """Write a Parquet file atomically and durably: `.<name>.<pid>.tmp` beside it (hidden from readers;
    the process id keeps two writers apart), flushed to disk, then renamed (`before_rename()` called just
    before: the tests' gate). A write that fails (a full disk) is an OutputError naming the file; nothing
    half-written stays, and what a killed writer left (temporary_names) is removed by the next sweep."""
    path = Path(path)
    tmp = temporary_name(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(tmp, "wb") as f:
            pq.write_table(table.replace_schema_metadata(metadata), f, compression="zstd")
            f.flush()
            os.fsync(f.fileno())
        if before_rename is not None:
            before_rename()
        os.replace(tmp, path)
        _fsync_dir(path.parent)
    except OSError as e:
        raise _cannot_write(path, e) from None
    finally:
        _discard(tmp)
    return path


def temporary_name(path: Path) -> Path:
    """Where write_table_atomic writes `path` before renaming it: `.<name>.<pid>.tmp` beside it."""
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


def stale_temporaries(path: Path) -> list[Path]:
    """The temporaries of `path` that killed writers left beside it (any process id)."""
    pattern = re.compile(rf"\.{re.escape(path.name)}\.\d+\.tmp")
    try:
        return [p for p in path.parent.iterdir() if pattern.fullmatch(p.name)]
    except OSError:
        return []


def write_part(folder: Path, index: int, table: pa.Table, metadata: dict[bytes, bytes]) -> Path:
    """One part of a dataset folder, written by write_table_atomic."""
    return write_table_atomic(folder / PART_NAME.format(index), table, metadata)


class ManifestError(Exception):
    """`_sweep.json` is there but cannot be read as a manifest (empty, cut short, not ours)."""


MANIFEST_KEYS = ("config_hash", "version", "grid_size", "chunk_runs", "parts")


def read_manifest(folder: Path) -> dict | None:
    """The manifest of a dataset folder; None when there is none; ManifestError when it is damaged."""
    path = Path(folder) / MANIFEST
    try:
        with open(path, "rb") as f:
            raw = f.read(64 * 2**20)
    except FileNotFoundError:
        return None
    except OSError as e:
        raise ManifestError(f"cannot read it ({e.strerror or e})") from None
    if not raw.strip():
        raise ManifestError("it is empty")
    try:
        m = json.loads(raw)
    except (UnicodeDecodeError, ValueError):
        raise ManifestError("it is cut short or not JSON") from None
    if not isinstance(m, dict) or any(k not in m for k in MANIFEST_KEYS):
        raise ManifestError("it is not a pounding_sweep manifest (no " + ", ".join(MANIFEST_KEYS) + ")")
    return m


def write_manifest(folder: Path, manifest: dict) -> None:
    """Atomically and durably, like a part."""
    path = folder / MANIFEST
    tmp = folder / f".{MANIFEST}.{os.getpid()}.tmp"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with open(tmp, "w") as f:
            f.write(json.dumps(manifest, indent=1, sort_keys=True))
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
        _fsync_dir(folder)
    except OSError as e:
        raise _cannot_write(path, e) from None
    finally:
        _discard(tmp)


def remove_stale_temporaries(folder: Path) -> None:
    """Parts and manifests a killed sweep left half-written (never renamed). Only ever called by the
    sweep holding the folder's lock (sweep/resume.py), so no running sweep's file is among them."""
    for t in list(Path(folder).glob(".part-*.tmp")) + list(Path(folder).glob(f".{MANIFEST}*.tmp")):
        if is_own_temporary(t.name):
            t.unlink(missing_ok=True)


def part_config_hash(path: Path) -> tuple[str | None, int]:
    """(config_hash, rows) of a part from its footer alone; (None, rows) for a Parquet file this package
    did not write. Raises OSError or pyarrow's ArrowInvalid for a file that is not whole Parquet."""
    meta = pq.read_metadata(path)
    kv = meta.metadata or {}
    if META_KEY not in kv or b"config_hash" not in kv:
        return None, meta.num_rows
    return kv[b"config_hash"].decode(errors="replace"), meta.num_rows


def part_config(path: Path) -> dict | None:
    """The canonical scene a part of ours was written from (None if it holds none)."""
    try:
        return json.loads(pq.read_metadata(path).metadata[META_KEY]).get("config")
    except Exception:  # noqa: BLE001 - only used to name a difference in a message
        return None


def sidecar_path(path: str | Path, what: str) -> Path:
    """`results/x.parquet` -> `results/x.<what>.parquet` (histories, best)."""
    p = Path(path)
    stem = p.name[: -len(".parquet")] if p.name.endswith(".parquet") else p.name
    return p.with_name(f"{stem}.{what}.parquet")


def histories_path(path: str | Path) -> Path:
    return sidecar_path(path, "histories")


def histories_table(run_ids: np.ndarray, hist: np.ndarray, dt_sample: float, columns: list[str]) -> pa.Table:
    """Long-format history table: run_id, t_s and one column per channel (units in the names)."""
    n_runs, n_ch, n_s = hist.shape
    cols = {"run_id": np.repeat(run_ids, n_s), "t_s": np.tile(np.arange(n_s) * dt_sample, n_runs)}
    for c, name in enumerate(columns):
        cols[name] = hist[:, c, :].reshape(-1)
    return arrow_table(cols)
