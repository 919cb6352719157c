"""What every command shares: the bad-input exit status, list parsing, and one-line errors."""

from __future__ import annotations

EXIT_BAD_INPUT = 2


def split_list(s: str) -> list[str]:
    """'a, b,,c' -> ['a', 'b', 'c']."""
    return [x.strip() for x in s.split(",") if x.strip()]


def numbers(s: str, n: int, what: str, cast=float) -> list:
    """n comma-separated numbers, or ValueError naming the option."""
    parts = split_list(s)
    try:
        vals = [cast(x) for x in parts]
    except ValueError:
        raise ValueError(f"{what} = {s!r}: expected {n} numbers separated by commas") from None
    if len(vals) != n:
        raise ValueError(f"{what} = {s!r}: expected {n} numbers separated by commas")
    return vals


class Bad(Exception):
    """A command-line problem: `<path>: <what> (<value>)`."""

    def __init__(self, path, what, value=None):
        super().__init__(f"{path}: {what}" + ("" if value is None else f" ({value})"))
