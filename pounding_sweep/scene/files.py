"""Reading a user's file, bounded: what is not a regular file (a FIFO would hang the reader, /dev/zero
never ends) is refused before a byte is read, and so is a file larger than its kind may be. The one home
of these limits; every reader of a scene, record or table goes through `open_regular` or `read_regular`.

A refusal is the caller's error class (ConfigError for a scene, RecordError for a record, ...) with one
line naming the file. No heavy import: the scene layer uses it before Numba, SciPy or pyarrow load.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

MiB = 2**20
#: the largest file of each kind read (a scene is a few kB; a 1,000,000-value list is about 5 MiB)
MAX_SCENE_BYTES = 16 * MiB
#: a record: 100,000,000 samples (records._MAX_SAMPLES) are never read from text; 256 MiB is ~17 M values
MAX_RECORD_BYTES = 256 * MiB
#: a tracked-displacement table: 3,000,000 rows of 10 channels are about 0.5 GiB of CSV
MAX_TABLE_BYTES = 2048 * MiB


def kind_of(mode: int) -> str:
    """What a file that is not a regular file is, in words."""
    for test, name in (
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def size_words(n: int) -> str:
    """1.5 GiB, 300 MiB, 12 kB, 5 bytes."""
    for unit, size in (("GiB", 2**30), ("MiB", MiB), ("kB", 1024)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n} bytes"


def open_regular(path, what: str, limit: int, error: type[Exception]):
    """Open `path` for reading in binary, or raise `error` naming it: missing, unreadable, a folder
    ("cannot read <what> (Is a directory)"), a FIFO, device or socket (never waits for a writer), or
    larger than `limit` bytes. Returns the open file (the caller closes it)."""
    p = str(path)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as e:
        raise error(f"{p}: cannot read {what} ({_strerror(e)})") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise error(f"{p}: cannot read {what} ({os.strerror(errno.EISDIR)})")
        if not stat.S_ISREG(st.st_mode):
            raise error(f"{p}: cannot read {what}: {kind_of(st.st_mode)}, not a regular file")
        if st.st_size > limit:
            raise error(f"{p}: {size_words(st.st_size)}, larger than the {size_words(limit)} {_a(what)} may be")
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular(path, what: str, limit: int, error: type[Exception]) -> bytes:
    """The whole of a regular file of at most `limit` bytes (open_regular's checks; a file that grows
    past the limit while read, or a /proc file that states size 0, is cut off and refused too)."""
    with open_regular(path, what, limit, error) as f:
        try:
            data = f.read(limit + 1)
        except OSError as e:
            raise error(f"{path}: cannot read {what} ({_strerror(e)})") from None
    if len(data) > limit:
        raise error(f"{path}: larger than the {size_words(limit)} {_a(what)} may be")
    return data


def not_text(raw: bytes) -> str | None:
    """Why bytes are not a text file a person wrote, as a phrase ("UTF-16 text", "binary data (a NUL
    byte at byte 7)"), or None when they are: UTF-16 or UTF-32 (a byte-order mark, or NUL bytes between
    the letters), binary data (a NUL or another control byte)."""
    head = raw[:4096]
    if head.startswith((b"\xff\xfe\x00\x00", b"\x00\x00\xfe\xff")):
        return "UTF-32 text"
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        return "UTF-16 text"
    nul = raw.find(b"\x00")
    if nul >= 0:
        odd, even = head[1::2], head[0::2]
        if len(head) >= 4 and max(odd.count(0) / len(odd), even.count(0) / len(even)) > 0.4:
            return "UTF-16 text"
        return f"binary data (a NUL byte at byte {nul})"
    bad = next((i for i, b in enumerate(head) if b < 32 and b not in b"\t\n\r\x0b\x0c\x1a"), None)
    if bad is not None:
        return f"binary data (control byte 0x{head[bad]:02x} at byte {bad})"
    return None


def text_problem(path, what: str, raw: bytes) -> str | None:
    """The one-line refusal of a file that should be text and is not (None: it is text)."""
    why = not_text(raw)
    if why is None:
        return None
    if why.startswith("UTF-"):
        return f"{path}: the {what} is {why}, not UTF-8 or ASCII: save it as UTF-8"
    return f"{path}: the {what} is {why}, not text"


def resolve(path: Path) -> Path:
    """`path` made absolute with symlinks followed where they can be; a symlink loop (Path.resolve
    raises RuntimeError before Python 3.13) or an unreadable folder leaves it absolute as written, so
    the reader of the file names the problem (ELOOP: 'Too many levels of symbolic links')."""
    try:
        return path.resolve()
    except (RuntimeError, OSError):
        return Path(os.path.abspath(path))


def _a(noun: str) -> str:
    return ("an " if noun[:1] in "aeiou" else "a ") + noun


def _strerror(e: OSError) -> str:
    return e.strerror or str(e)
