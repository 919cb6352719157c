"""The output folder of a sweep: claimed before anything is computed, resumed where an interrupted run
of the same sweep left it, or refused; on failure, left as it was found.

* Claimed: the folder (and the histories folder) is created or found, and locked: an exclusive
  `flock` on `._sweep.lock` inside it, held while the sweep runs, so a second sweep aimed at the same
  folder is refused at once (it would otherwise share the parts' names), and only the lock's holder
  removes temporaries a killed sweep left. Creating the lock is also the check that results can be
  written there (a read-only disk, /proc, a name too long), before the grid is computed.
* Resumed: only parts this very sweep wrote are kept. The manifest (`_sweep.json`) must hold the same
  config hash, package version and chunking; every part's own `config_hash` (Parquet key-value
  metadata) must equal the manifest's, and its row count its chunk's; a chunk whose history part is
  missing is run again. A part of another sweep, a part cut short, a file that is not ours named like a
  part, or a damaged manifest is refused by name: resuming would mix or lose rows.
* Refused, never deleted: a user's file at the output path, a folder that is not a sweep's (no
  manifest), a part this package did not write. `--overwrite` deletes only what is provably a sweep's
  own: the parts (Parquet files carrying this package's metadata), the manifest, the histories' parts
  and the best-runs file of a folder that has a manifest.
* Released: the lock is dropped; when the sweep wrote nothing (bad input found late, an interrupt
  before the first part), the folders it created and the manifest it wrote are removed again.
"""

from __future__ import annotations

import os
from pathlib import Path

from pounding_sweep.errors import OutputError
from pounding_sweep.scene.hashing import differences
from pounding_sweep.sweep.results import (
    MANIFEST,
    META_KEY,
    PART_NAME,
    ManifestError,
    is_own_temporary,
    part_config,
    part_config_hash,
    part_files,
    part_index,
    read_manifest,
    remove_stale_temporaries,
    stale_temporaries,
    write_manifest,
)

try:
    import fcntl
except ImportError:  # not POSIX: no lock; the temporaries' names still carry the process id
    fcntl = None

LOCK = "._sweep.lock"


class OutputFolder:
    """One sweep's hold on its output: `claim()` before computing, `resume(manifest)` once the sweep's
    chunking is known, `manifest_written(...)` / `wrote_part()` as it writes, `release(ok)` at the end."""

    def __init__(self, out: Path, hpath: Path | None, overwrite: bool, best: Path | None = None):
        self.out, self.hpath, self.overwrite, self.best = Path(out), hpath, overwrite, best
        self._created: list[Path] = []  # folders this sweep made, outermost first
        self._locks: list[tuple[int, Path]] = []
        self._manifest_ours = False  # this sweep wrote the manifest
        self.parts_written = 0

    # ------------------------------------------------------------------ claim

    def claim(self) -> OutputFolder:
        folders = [f for f in (self.out, self.hpath) if f is not None]
        for f in folders:
            _refuse_non_folder(f)
        if self.best is not None:
            _refuse_foreign_file(self.best, "its best runs", self.out)
        try:
            for f in folders:
                self._make(f)
            for f in folders:
                self._locks.append(_lock(f))
            if self.best is not None:  # two result folders may share it (--out r/x and r/x.parquet)
                self._locks.append(_lock(self.best.parent, f".{self.best.name}.lock", self.best))
                for t in stale_temporaries(self.best):  # a sweep killed while writing it (ours: we hold its lock)
                    t.unlink(missing_ok=True)
        except BaseException:
            self.release(ok=False)
            raise
        return self

    def _make(self, folder: Path) -> None:
        """Create `folder` and any missing parents, remembering which (release removes them if unused)."""
        missing = []
        p = folder
        while not p.exists() and not p.is_symlink() and p != p.parent:
            missing.append(p)
            p = p.parent
        for p in reversed(missing):
            try:
                p.mkdir()
            except FileExistsError:
                continue
            except OSError as e:
                raise OutputError(f"{folder}: cannot create the results folder here ({_why(e)})") from None
            self._created.append(p)

    # ------------------------------------------------------------------ resume

    def resume(self, manifest: dict) -> set[int]:
        """Indexes of the parts already finished for this very sweep; refuse anything else in the folders.
        `manifest` is the new one (with the canonical config under "config")."""
        out = self.out
        for f in (out, self.hpath):  # what killed sweeps left half-written (none runs now: the lock is ours)
            if f is not None:
                remove_stale_temporaries(f)
        try:
            old = read_manifest(out)
        except ManifestError as e:
            if not self.overwrite:
                raise OutputError(
                    f"{out / MANIFEST}: {e}; the results in this folder cannot be resumed: give another "
                    "--out, or --overwrite to replace them"
                ) from None
            old = {}
        if self.overwrite and old is not None:
            self._clear()
            return set()
        if old is None:
            for f in (out, self.hpath):
                if f is not None and (extra := _entries(f)):
                    raise OutputError(
                        f"{f} exists and is not a pounding_sweep result folder (no {MANIFEST}; it holds "
                        f"{_listing(extra)}): give another --out"
                    )
            return set()
        reasons = _manifest_differences(old, manifest)
        if reasons:
            raise OutputError(
                f"{out} holds results of a different sweep ({'; '.join(reasons)}); resuming would mix them: "
                "give another --out, or --overwrite to replace them"
            )
        done = self._check_parts(out, manifest, rows=True)
        if self.hpath is not None:
            done &= self._check_parts(self.hpath, manifest, rows=False)  # a history part missing: run again
        return done

    def _check_parts(self, folder: Path, manifest: dict, rows: bool) -> set[int]:
        n, size, chunk = manifest["parts"], manifest["grid_size"], manifest["chunk_runs"]
        done = set()
        for p in part_files(folder):
            i = part_index(p)
            if i >= n:
                raise OutputError(
                    f"{p}: beyond the {n} parts of this sweep (the last is {PART_NAME.format(n - 1)}); resuming "
                    "would mix it in: move it away, give another --out, or --overwrite"
                )
            try:
                h, count = part_config_hash(p)
            except Exception:  # noqa: BLE001 - pyarrow's errors for a file that is not whole Parquet vary
                raise OutputError(
                    f"{p}: cannot be read as Parquet (cut short or damaged); delete it and run the same command "
                    "again to recompute it"
                ) from None
            if h is None:
                raise OutputError(
                    f"{p}: not a part this package wrote (no '{META_KEY.decode()}' metadata); resuming would mix "
                    "it in: move it away, or give another --out"
                )
            if h != manifest["config_hash"]:
                what = differences(part_config(p) or {}, manifest.get("config") or {}) or [f"config_hash {h[:12]}"]
                raise OutputError(
                    f"{p}: a part of a different sweep ({'; '.join(what)}); resuming would mix them: delete it "
                    "(it is recomputed), give another --out, or --overwrite"
                )
            expected = min(chunk, size - i * chunk)
            if rows and count != expected:
                raise OutputError(
                    f"{p}: {count} rows, not the {expected} runs of this part (damaged); delete it and run the "
                    "same command again to recompute it"
                )
            done.add(i)
        return done

    def _clear(self) -> None:
        """--overwrite: delete this sweep folder's parts, manifest, histories and best runs, once every part
        file there has been shown to be ours (a Parquet file with this package's metadata)."""
        doomed = []
        for f in (self.out, self.hpath):
            if f is None:
                continue
            for p in part_files(f):
                try:
                    ours = part_config_hash(p)[0] is not None
                except Exception:  # noqa: BLE001 - unreadable: cannot be shown to be ours
                    ours = False
                if not ours:
                    raise OutputError(
                        f"{p}: not a part this package wrote (or cut short); --overwrite deletes only a sweep's own "
                        "parts: move it away, or give another --out"
                    )
                doomed.append(p)
        for p in doomed + [self.out / MANIFEST]:
            p.unlink(missing_ok=True)
        if self.best is not None and self.best.is_file():
            self.best.unlink()

    # ------------------------------------------------------------------ writing

    def write_manifest(self, manifest: dict) -> None:
        """The manifest, before the first part (a part without a manifest could not be resumed)."""
        if not (self.out / MANIFEST).exists():
            write_manifest(self.out, manifest)
            self._manifest_ours = True

    def wrote_part(self) -> None:
        self.parts_written += 1

    # ------------------------------------------------------------------ release

    def release(self, ok: bool) -> None:
        """Drop the locks; after a failure that wrote no part, remove what this sweep created."""
        if not ok and self.parts_written == 0:
            if self._manifest_ours:
                (self.out / MANIFEST).unlink(missing_ok=True)
                remove_stale_temporaries(self.out)
        for fd, path in reversed(self._locks):
            try:
                path.unlink(missing_ok=True)
            except OSError:
                pass
            os.close(fd)
        self._locks.clear()
        if not ok and self.parts_written == 0:
            for p in reversed(self._created):
                try:
                    p.rmdir()  # only if empty: never removes anything but our own empty folder
                except OSError:
                    pass
            self._created.clear()


# ----------------------------------------------------------------------------- helpers


def _refuse_non_folder(path: Path) -> None:
    """A file (or a FIFO, a device) at the output path is the user's: refused, never replaced."""
    import errno
    import stat

    from pounding_sweep.scene.files import kind_of

    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        if path.is_symlink():
            raise OutputError(f"{path}: a symbolic link to nothing: give another --out") from None
        return  # to be made
    except NotADirectoryError:
        return  # a file on the way: creating the folder says so
    except OSError as e:  # a name too long, a symlink loop, no permission to look
        if e.errno == errno.ENAMETOOLONG:
            raise OutputError(f"{path}: cannot create the results folder here ({_why(e)})") from None
        raise OutputError(f"{path}: cannot use this path for results ({_why(e)})") from None
    if stat.S_ISDIR(mode):
        return
    if stat.S_ISREG(mode):
        raise OutputError(
            f"{path} is a file, not a results folder (a sweep writes a folder of Parquet parts there): give "
            "another --out, or move the file away"
        )
    raise OutputError(f"{path}: not a folder ({kind_of(mode)}): give another --out")


def _refuse_foreign_file(path: Path, what: str, out: Path) -> None:
    """A file a sweep writes beside its folder (the best runs) may replace only an earlier one of ours, written for
    the same result folder: `--out r/x` and `--out r/x.parquet` both name r/x.best.parquet (the table records its
    folder's name; one written before it did is taken as this folder's)."""
    if not (path.exists() or path.is_symlink()):
        return
    ours, info = False, {}
    if path.is_file():
        try:
            import json

            import pyarrow.parquet as pq

            kv = pq.read_metadata(path).metadata or {}
            ours = META_KEY in kv
            info = json.loads(kv[META_KEY]) if ours else {}
        except Exception:  # noqa: BLE001 - not Parquet, or damaged: not shown to be ours
            ours = False
    if not ours:
        raise OutputError(
            f"{path}: exists and is not a file this package wrote; the sweep writes {what} there: move it "
            "away, or give another --out"
        )
    owner = info.get("results") if isinstance(info, dict) else None
    if owner is not None and owner != out.name:
        raise OutputError(
            f"{path}: holds the best runs of the results in {out.with_name(owner)}, not of {out}, and the sweep "
            f"writes {what} there: give another --out (one whose name does not share {path.name})"
        )


def _lock(folder: Path, name: str = LOCK, what: Path | None = None) -> tuple[int, Path]:
    """Create and lock `folder/<name>` (`._sweep.lock`; exclusive, not waiting); refuse when another sweep holds
    it (`what`: the file it guards, named in the refusal; default the folder). Creating it is also the first
    write into the folder: where nothing can be written, this says so."""
    path = folder / name
    what = what or folder
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as e:
            raise OutputError(f"{folder}: cannot write results here ({_why(e)})") from None
        if fcntl is None:
            return fd, path
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            raise OutputError(
                f"{what}: another sweep is writing to this {'folder' if what == folder else 'file'}{holder}; wait "
                "for it to finish, or give another --out"
            ) from None
        except OSError:  # a file system without locks (some network mounts): go on unlocked
            return fd, path
        try:  # the holder before us may have removed the file between our open and lock: lock the new one
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            try:
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}\n".encode())
            except OSError:  # a full disk: the lock holds without the process id
                pass
            return fd, path
        os.close(fd)


def _holder(fd: int) -> str:
    try:
        pid = os.pread(fd, 32, 0).decode().strip()
    except (OSError, UnicodeDecodeError):
        return ""
    return f" (process {pid})" if pid.isdigit() else ""


def _entries(folder: Path) -> list[str]:
    """What a folder holds besides a sweep's own temporaries and lock."""
    try:
        return sorted(p.name for p in folder.iterdir() if not is_own_temporary(p.name))
    except (FileNotFoundError, NotADirectoryError):
        return []


def _listing(names: list[str]) -> str:
    shown = ", ".join(names[:3])
    return shown + (f" and {len(names) - 3} more" if len(names) > 3 else "")


def _manifest_differences(old: dict, new: dict) -> list[str]:
    """Why an existing manifest is not this sweep's, naming the keys (the scene's, where it is stored)."""
    if old.get("config_hash") != new["config_hash"]:
        if isinstance(old.get("config"), dict):
            found = differences(old["config"], new["config"])
            if found:
                return found
        return [f"config_hash {str(old.get('config_hash'))[:12]}... there, {new['config_hash'][:12]}... now"]
    reasons = []
    if old.get("version") != new["version"]:
        reasons.append(f"package version {old.get('version')} there, {new['version']} now")
    if old.get("grid_size") != new["grid_size"]:
        reasons.append(f"{old.get('grid_size')} runs there, {new['grid_size']} now")
    if old.get("chunk_runs") != new["chunk_runs"] or old.get("parts") != new["parts"]:
        reasons.append(
            f"[execution] chunk_runs = {old.get('chunk_runs')} there ({old.get('parts')} parts), "
            f"{new['chunk_runs']} now ({new['parts']} parts)"
        )
    return reasons


def _why(e: OSError) -> str:
    return e.strerror or str(e)
