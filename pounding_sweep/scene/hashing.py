"""The canonical form of a scene and its SHA-256: what identifies a sweep (Parquet metadata, resume)."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path


def canonical(scene) -> dict:
    """Resolved scene as plain data (what the hash covers), with record file digests. How and
    where it runs ([execution], the output path) is left out: it does not change a result, so a
    sweep can be resumed on another executor or after its folder moved."""
    d = dataclasses.asdict(scene)
    d.pop("source")
    d.pop("toml_text")
    d.pop("execution")
    d["output"].pop("path")
    d["sweep"] = [{"name": a.name, "values": list(a.values)} for a in scene.sweep]
    files = sorted(({scene.excitation.record} | set(scene.axis_values("record"))) - {None})
    if scene.experiment is not None:
        x = scene.experiment
        files.append(x.video.path if x.video is not None else x.table)
    d["record_sha256"] = {Path(p).name: file_digest(p) for p in files}
    return d


def config_hash(scene) -> str:
    blob = json.dumps(canonical(scene), sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()


def file_digest(path: str) -> str:
    """SHA-256 of a file, read in 1 MiB blocks (a video may be larger than memory wants)."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return "unreadable"
    return h.hexdigest()
