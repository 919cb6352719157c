"""The canonical form of a scene and its SHA-256: what identifies a sweep (Parquet metadata, resume).

No absolute path enters it: every file a scene names (records, the experiment's table or video) is
there by its file name and the SHA-256 of its content, so a project folder that moves, or the same
scene in another checkout or on another machine, hashes the same, and a file whose content changed
does not. `differences` names the keys in which two canonical forms differ (a refused resume says
which)."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

from pounding_sweep.scene.groups import SPLIT_LATER, metric_group_names

#: [experiment] keys added after scenes were first hashed (acceleration channels), with the values they had
#: before they existed: at these values they are left out of the canonical form, so a scene that does not
#: use them keeps its hash (and its results resume). Written out, not read from the schema: were a default
#: ever changed, a scene at the new default would differ from these values and hash differently, as it must.
ADDED_EXPERIMENT_KEYS = {
    "acc_units": "m/s2",
    "lowpass_Hz": None,
    "lowpass_order": 4,
    "use": "both",
    "weights": "equal",
    "noise": None,
    "noise_window_s": None,
    "sensor_filter": "none",
    "sensor_rate_Hz": None,
    "sensor_cutoff_Hz": None,
    "sensor_order": 2,
}
#: [excitation] keys and sections added for ensembles of ground motions (intensity measures, stochastic
#: motions), left out at the values they had before they existed, like ADDED_EXPERIMENT_KEYS
ADDED_EXCITATION_KEYS = {"intensity": "none", "scaling": "factor", "intensity_period_s": None}
ADDED_SECTIONS = ("stochastic",)
#: [buildingN] keys added later (per-story stiffness factors, per-mode damping), left out at the values they had before they existed
ADDED_BUILDING_KEYS = {"story_stiffness_scales": None, "modal_damping_ratios": None}


def canonical(scene) -> dict:
    """Resolved scene as plain JSON data (what the hash covers). How and where it runs ([execution],
    the output path) is left out: it does not change a result, so a sweep can be resumed on another
    executor or after its folder moved. Files are {"file": name, "sha256": digest}."""
    d = dataclasses.asdict(scene)
    d.pop("source")
    d.pop("toml_text")
    d.pop("execution")
    d.pop("calibrate", None)  # the fit after the grid: changes no run of the grid (its parts resume)
    d.pop("risk", None)  # the study over the runs ([risk]): changes no run either
    for key, before in ADDED_EXCITATION_KEYS.items():
        if d["excitation"].get(key, before) == before:
            d["excitation"].pop(key, None)
    for section in ADDED_SECTIONS:
        if d.get(section, 0) is None:
            del d[section]
    for building in ("building1", "building2"):
        for key, before in ADDED_BUILDING_KEYS.items():
            if d.get(building) is not None and d[building].get(key, before) == before:
                d[building].pop(key, None)
    d["output"] = _output(d["output"])
    digests: dict[str, dict] = {}

    def file(path):
        if path is None:
            return None
        if path not in digests:
            digests[path] = {"file": Path(path).name, "sha256": file_digest(path)}
        return digests[path]

    d["excitation"]["record"] = file(scene.excitation.record)
    d["sweep"] = [
        {"name": a.name, "values": [file(v) for v in a.values] if a.name == "record" else list(a.values)}
        for a in scene.sweep
    ]
    if scene.experiment is not None:
        x = d["experiment"]
        for key, before in ADDED_EXPERIMENT_KEYS.items():
            if x[key] == before:
                del x[key]
        x["table"] = file(scene.experiment.table)
        if x.get("video") is not None:
            x["video"]["path"] = file(scene.experiment.video.path)
    return json.loads(json.dumps(d, sort_keys=True, default=str))  # plain JSON types: tuples as lists


def _output(out: dict) -> dict:
    """[output] as hashed: no path (where results go changes none of them); metrics, added later, absent at its
    default (every group) as before it existed, else the groups it names in one order (another order computes
    the same); the groups split off later (scene/groups.py SPLIT_LATER) named only where left out, as no_<group>."""
    out = {k: v for k, v in out.items() if k != "path"}
    metrics = out.pop("metrics", None)
    if metrics is not None:
        names = metric_group_names(tuple(metrics))
        kept = [g for g in names if g not in SPLIT_LATER]
        out["metrics"] = kept + [f"no_{g}" for g in SPLIT_LATER if g not in names]
    return out


def config_hash(scene) -> str:
    return hash_of(canonical(scene))


def hash_of(canonical_form: dict) -> str:
    """SHA-256 of a canonical form (as canonical() gives it, or as a manifest stored it)."""
    blob = json.dumps(canonical_form, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()


def differences(old: dict, new: dict, limit: int = 3) -> list[str]:
    """The first `limit` keys in which two canonical forms differ, each as
    "[section] key = OLD there, NEW now" (a file by its name and the start of its digest)."""
    out: list[str] = []

    def show(v) -> str:
        if isinstance(v, dict) and set(v) == {"file", "sha256"}:
            return f"{v['file']} (sha256 {str(v['sha256'])[:12]})"
        text = json.dumps(v, sort_keys=True)
        return text if len(text) <= 60 else text[:57] + "..."

    def walk(a, b, key: str) -> None:
        if len(out) >= limit or a == b:
            return
        if isinstance(a, dict) and isinstance(b, dict) and not ({"file", "sha256"} == set(a) == set(b)):
            for k in sorted(set(a) | set(b)):
                walk(a.get(k), b.get(k), f"{key} {k}" if key.endswith("]") else f"{key}.{k}")
            return
        out.append(f"{key or 'the scene'} = {show(a)} there, {show(b)} now")

    def axes(form: dict):
        sweep = form.get("sweep") or []
        return [a.get("name") for a in sweep], {a.get("name"): a.get("values") for a in sweep}

    (na, va), (nb, vb) = axes(old), axes(new)
    if na != nb:
        out.append(f"[sweep] axes = {show(na)} there, {show(nb)} now")
    else:
        walk(va, vb, "[sweep]")
    for k in sorted((set(old) | set(new)) - {"sweep"}):
        a, b = old.get(k), new.get(k)
        if isinstance(a, dict) or isinstance(b, dict):
            walk(a, b, f"[{k}]")
        else:
            walk(a, b, k)
    return out[:limit]


def file_digest(path: str) -> str:
    """SHA-256 of a file, read in 1 MiB blocks (a video may be larger than memory wants). What is not a
    regular file (a FIFO would never end) is not read: its digest is a word saying so."""
    import os
    import stat

    h = hashlib.sha256()
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return "unreadable"
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return "not a regular file"
        os.set_blocking(fd, True)
        with os.fdopen(os.dup(fd), "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return "unreadable"
    finally:
        os.close(fd)
    return h.hexdigest()
