"""Errors a user's input can cause, one class per kind of input, each a one-line message naming the
file, the key and the value. Every layer raises them and imports nothing to do so (this module imports
nothing); the command line prints each as `error: ...` and exits with status 2."""

from __future__ import annotations


class InputError(ValueError):
    """Input that cannot be used: the message names the file, the key (or line) and the value."""


class ConfigError(InputError):
    """A scene that cannot be run: the message names the file, the key and the value."""


class OutputError(ConfigError):
    """The output folder holds results this sweep must not mix with or overwrite unasked."""


class RecordError(InputError):
    """Bad ground-motion file: the message names the file, the line (when known) and the offending value."""


class ExperimentError(InputError):
    """A tracked-displacement table that cannot be scored against: names the file and column."""


class SensorError(InputError):
    """A raw sensor export that cannot be imported (model/sensors): names the file, the line or column, the value."""


class ResultError(InputError):
    """A file given as a sweep's result that is not one (a scene, a histories dataset, a best table):
    the message names the file, what it is, and what to give instead."""


class VideoError(InputError):
    """A video, or a tracking request, that cannot give a trustworthy displacement table.

    `str(e)` is one line: `<file>: <what> (<value>)`.
    """

    def __init__(self, path, what: str, value=None):
        self.path, self.what, self.value = str(path), what, value
        super().__init__(f"{path}: {what}" + ("" if value is None else f" ({value})"))


class ClusterError(InputError):
    """A Dask scheduler that cannot be reached or was lost: one line naming the address; the parts
    written so far are kept, and the same command resumes."""


def shown(value, width: int = 80) -> str:
    """repr(value) for a one-line message, cut to about `width` characters: a list of a million values
    or a string of a megabyte is shown by its start and its length, never whole."""
    import reprlib

    r = reprlib.Repr()
    r.maxlist = r.maxtuple = r.maxdict = r.maxset = 8
    r.maxlevel = 3
    r.maxstring = r.maxother = r.maxlong = width
    text = r.repr(value)
    if isinstance(value, str) and len(value) > width:
        text += f" ({len(value):,} characters)"
    elif isinstance(value, list | tuple | dict) and len(value) > 8:
        text += f" ({len(value):,} values)"
    return text
