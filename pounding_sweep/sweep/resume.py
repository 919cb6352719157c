"""The output folder of a sweep: claimed for this sweep, resumed where an interrupted run of the same
sweep left it, or refused (another sweep's results, or something that is not ours)."""

from __future__ import annotations

from pathlib import Path

from pounding_sweep.errors import OutputError
from pounding_sweep.sweep.results import (
    MANIFEST,
    part_files,
    part_index,
    read_manifest,
    remove_stale_temporaries,
    sidecar_path,
)


def claim_output(out: Path, hpath: Path | None, manifest: dict, overwrite: bool) -> set[int]:
    """Indexes of the parts already finished for this very sweep; refuse anything else in `out`."""
    if out.is_file():
        if not overwrite:
            raise OutputError(f"{out} is a file (an older single-file result?): give another --out, or --overwrite")
        out.unlink()
    if not out.exists():
        return set()
    old = read_manifest(out)
    if overwrite:
        for folder in (out, hpath):
            if folder is not None and folder.is_dir():
                for f in part_files(folder) + [folder / MANIFEST]:
                    f.unlink(missing_ok=True)
        sidecar_path(out, "best").unlink(missing_ok=True)
        return set()
    if old is None:
        if any(out.iterdir()):
            raise OutputError(
                f"{out} exists and is not a pounding_sweep result folder (no {MANIFEST}): give another --out"
            )
        return set()
    same = {k: old.get(k) == v for k, v in manifest.items() if k != "scene"}
    if not all(same.values()):
        what = ", ".join(f"{k} {old.get(k)!r} here vs {manifest[k]!r} now" for k, ok in same.items() if not ok)
        raise OutputError(
            f"{out} holds results of a different sweep ({what}); resuming would mix them: "
            "give another --out, or --overwrite to replace them"
        )
    remove_stale_temporaries(out)
    if hpath is not None and hpath.is_dir():
        remove_stale_temporaries(hpath)
    return {part_index(p) for p in part_files(out) if part_index(p) < manifest["parts"]}
