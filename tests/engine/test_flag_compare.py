"""engine/flag_compare.py: compile flags hash and compare as Numba's own methods say, pair for pair."""

from __future__ import annotations

import itertools

import pytest
from numba.core import targetconfig
from numba.core.compiler import Flags

from pounding_sweep.engine import flag_compare, jit  # noqa: F401 (jit installs the patches)

TargetConfig = targetconfig.TargetConfig
installed = pytest.mark.skipif(
    not getattr(TargetConfig.__hash__, "hashes_by_class", False),
    reason=f"this Numba's TargetConfig methods (source digest {flag_compare.source_digest()}) are not the ones "
    "engine/flag_compare.py was written against (KNOWN_SOURCES): nothing installed, the kernels compile more "
    "slowly to the same code; read the new methods and add their digest if the module's reasoning still holds",
)


class _MoreFlags(Flags):
    """A subclass with an option of its own (as CUDA's flags are): never equal to a Flags by the shortcut."""

    extra = targetconfig.Option(type=bool, default=False, doc="an option Flags has not")


def _flags(cls=Flags, **set_options):
    f = cls()
    for name, value in set_options.items():
        setattr(f, name, value)
    return f


def _cases():
    """Flags that differ in what is set, in values, in class, and one set explicitly to its default (equal to
    one where it is not set: the shortcut does not decide that pair, Numba's comparison does)."""
    return [
        _flags(),
        _flags(nrt=True),
        _flags(nrt=True, boundscheck=False),
        _flags(boundscheck=False, nrt=True),  # the same options set in the other order
        _flags(nrt=False),
        _flags(nrt=Flags.options["nrt"].default),
        _flags(error_model="numpy", nrt=True),
        _flags(_MoreFlags),
        _flags(_MoreFlags, nrt=True),
        _flags(_MoreFlags, extra=True),
    ]


@installed
def test_the_same_answers_as_numbas_own_methods():
    numba_hash = TargetConfig.__hash__.__wrapped__
    numba_eq = TargetConfig.__eq__.__wrapped__
    cases = _cases()
    for a in cases:
        assert hash(a) == numba_hash(a)
    for a, b in itertools.product(cases, repeat=2):
        assert (a == b) == numba_eq(a, b), (a, b)
        assert (a != b) == (not numba_eq(a, b)), (a, b)
    assert (cases[0] == object()) is False  # another type: Numba's NotImplemented, then identity
    # the pairs above reach both branches: equal by the shortcut, and equal only by Numba's comparison
    assert cases[2]._values == cases[3]._values and cases[2] == cases[3]
    assert cases[0]._values != cases[5]._values and cases[0] == cases[5]


@installed
def test_a_dict_keyed_by_flags_finds_what_numba_would():
    """The overload templates' cache: keys (arguments, flags) find their entry, and only theirs."""
    cases = _cases()
    table = {("args", f): i for i, f in enumerate(cases)}  # equal flags share one entry, as with Numba's methods
    for f in cases:
        expected = max(i for i, g in enumerate(cases) if TargetConfig.__eq__.__wrapped__(f, g))
        assert table[("args", f)] == expected


@installed
def test_install_is_idempotent_and_known():
    assert flag_compare.install()
    assert flag_compare.source_digest() in flag_compare.KNOWN_SOURCES
    assert TargetConfig.__eq__.__wrapped__.__module__ == "numba.core.targetconfig"
