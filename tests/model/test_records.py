"""Tests for pounding_sweep.model.records: AT2/CSV readers, error messages, similitude, resampling.

Tolerances: a value read from text is correctly rounded (Python's float, u relative) and a unit factor
applied to it rounds once more, against an expected value that is itself one or two roundings away:
rtol 1e-15 is 4.5 u, 1e-14 allows the factor's own representation error (9.80665 is not binary)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED

from pounding_sweep.model.records import (
    G_STANDARD,
    GroundRecord,
    RecordError,
    read_at2,
    read_csv_record,
    read_record,
    resample,
    similitude_scale,
)

GM_DIR = SHARED / "data" / "ground_motions"

# file -> (NPTS, DT, published PGA in g)
PUBLISHED = {
    "RSN1605_DUZCE_DZC180.AT2": (5177, 0.005, 0.4043),
    "RSN1605_DUZCE_DZC270.AT2": (5177, 0.005, 0.5150),
    "RSN1602_DUZCE_BOL000.AT2": (5590, 0.010, 0.7392),
    "RSN1602_DUZCE_BOL090.AT2": (5590, 0.010, 0.8057),
    "RSN1616_DUZCE_362-E.AT2": (4316, 0.010, 0.0283),
    "RSN6_IMPVALL.I_I-ELC180.AT2": (5372, 0.010, 0.2808),
    "IELC180.AT2": (4000, 0.010, 0.3129),
}


@pytest.fixture(scope="module")
def gm_dir() -> Path:
    if not GM_DIR.is_dir() or not any(GM_DIR.glob("*.AT2")):
        pytest.skip(f"../shared/data/ground_motions not present: no .AT2 files in {GM_DIR}")
    return GM_DIR


def _gm_file(gm_dir: Path, name: str) -> Path:
    p = gm_dir / name
    if not p.is_file():
        pytest.skip(f"../shared/data/ground_motions not present: {name} missing from {gm_dir}")
    return p


# --------------------------------------------------------------------------- real files


def test_every_at2_parses_and_matches_its_header(gm_dir):
    files = sorted(gm_dir.glob("*.AT2"))
    assert files
    for f in files:
        lines = f.read_text().splitlines()
        npts = int(lines[3].split("NPTS=")[1].split(",")[0])
        dt = float(lines[3].split("DT=")[1].split()[0])
        rec = read_at2(f)
        assert rec.name == f.stem
        assert rec.source == str(f)
        assert rec.acc_m_s2.shape == (npts,), f.name
        assert rec.acc_m_s2.dtype == np.float64
        assert rec.dt_s == pytest.approx(dt, rel=1e-12), f.name
        assert rec.duration_s == pytest.approx((npts - 1) * dt), f.name
        assert rec.description == lines[1].strip()
        assert np.all(np.isfinite(rec.acc_m_s2))
        # first value on line 5, in g, converted to m/s^2
        assert rec.acc_m_s2[0] == pytest.approx(float(lines[4].split()[0]) * G_STANDARD, rel=1e-12)


@pytest.mark.parametrize("name", sorted(PUBLISHED))
def test_published_npts_dt_pga(gm_dir, name):
    npts, dt, pga_g = PUBLISHED[name]
    rec = read_record(_gm_file(gm_dir, name))
    assert rec.acc_m_s2.size == npts
    assert rec.dt_s == pytest.approx(dt, rel=1e-12)
    assert round(rec.pga_m_s2 / G_STANDARD, 4) == pytest.approx(pga_g, abs=1e-12)


def test_dzc180_time_of_pga_and_description(gm_dir):
    rec = read_at2(_gm_file(gm_dir, "RSN1605_DUZCE_DZC180.AT2"))
    t_pga = rec.time_s[np.argmax(np.abs(rec.acc_m_s2))]
    assert abs(t_pga - 4.78) <= rec.dt_s
    assert rec.description == "Duzce Turkey, 11/12/1999, Duzce, 180"
    assert rec.duration_s == pytest.approx(5176 * 0.005)


def test_crlf_and_older_header_descriptions(gm_dir):
    crlf = read_at2(_gm_file(gm_dir, "RSN1616_DUZCE_362-E.AT2"))
    assert crlf.description == "Duzce Turkey, 11/12/1999, Lamont 362, E"  # no stray '\r'
    old = read_at2(_gm_file(gm_dir, "IELC180.AT2"))
    assert old.description.startswith("IMPERIAL VALLEY 5/19/40 0439, EL CENTRO ARRAY #9, 180")
    assert old.acc_m_s2[0] == pytest.approx(-0.6403182e-02 * G_STANDARD, rel=1e-12)


def test_record_is_read_only(gm_dir):
    rec = read_at2(_gm_file(gm_dir, "RSN1605_DUZCE_DZC180.AT2"))
    assert not rec.acc_m_s2.flags.writeable
    with pytest.raises(ValueError):
        rec.acc_m_s2[0] = 1.0


# --------------------------------------------------------------------------- synthetic AT2

NGA_HEAD = (
    "PEER NGA STRONG MOTION DATABASE RECORD\nTest Event, 1/1/2000, Station, 0\nACCELERATION TIME SERIES IN UNITS OF G\n"
)


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_synthetic_at2_values_units_and_header_variants(tmp_path):
    body = "  -.1000000E-01   .2000000E+00\n   .5E-01\n"
    p = _write(tmp_path, "a.AT2", NGA_HEAD + "NPTS=      3, DT=   .0050 SEC,   \n" + body)
    rec = read_at2(p)
    assert G_STANDARD == 9.80665
    np.testing.assert_allclose(rec.acc_m_s2, [-0.0980665, 1.96133, 0.4903325], rtol=1e-14)
    assert rec.dt_s == 0.005
    assert rec.time_s.tolist() == pytest.approx([0.0, 0.005, 0.010])
    assert rec.pga_m_s2 == pytest.approx(0.2 * G_STANDARD)
    # explicit units agreeing with the header are fine
    np.testing.assert_allclose(read_at2(p, units="g").acc_m_s2, rec.acc_m_s2, rtol=0)
    # explicit units where the header names none: they are the record's
    p0 = _write(tmp_path, "a0.AT2", NGA_HEAD.replace(" IN UNITS OF G", "") + "NPTS= 3, DT= .005\n" + body)
    np.testing.assert_allclose(read_at2(p0).acc_m_s2, rec.acc_m_s2, rtol=0)  # PEER's convention: g
    np.testing.assert_allclose(read_at2(p0, units="gal").acc_m_s2, [-1e-4, 2e-3, 5e-4], rtol=1e-14)
    np.testing.assert_allclose(read_at2(p0, units="m/s^2").acc_m_s2, [-0.01, 0.2, 0.05], rtol=1e-15)
    # spaced variant of line 4
    p2 = _write(tmp_path, "b.AT2", NGA_HEAD + "NPTS = 3 DT = 0.01\n" + body)
    assert read_at2(p2).dt_s == 0.01
    # header naming cm/s/s, units left at default -> header wins
    head_cm = NGA_HEAD.replace("UNITS OF G", "UNITS OF CM/SEC/SEC")
    p3 = _write(tmp_path, "c.AT2", head_cm + "NPTS=3, DT=.01 SEC\n" + body)
    np.testing.assert_allclose(read_at2(p3).acc_m_s2, [-1e-4, 2e-3, 5e-4], rtol=1e-14)


# line 3 of AT2 files from elsewhere than PEER: how each names its units -> the units read
HEADER_FORMS = {
    "ACCELERATION TIME SERIES IN UNITS OF G": "g",
    "ACCELERATION IN G": "g",
    "Acceleration (g)": "g",
    "UNITS: G": "g",
    "ACCELERATION TIME SERIES IN UNITS OF CM/SEC/SEC": "cm/s2",
    "ACCELERATION IN CM/S2": "cm/s2",
    "Acceleration (cm/s^2)": "cm/s2",
    "acceleration in cm/sec**2": "cm/s2",
    "accel cm.s-2": "cm/s2",
    "acceleration [cm s^-2]": "cm/s2",
    "acceleration in cm/s²": "cm/s2",
    "UNITS: GAL": "cm/s2",
    "Acceleration in gals": "cm/s2",
    "ACCELERATION IN M/S/S": "m/s2",
    "acceleration [m/s**2]": "m/s2",
    "ACCELERATION TIME HISTORY": "g",  # no units named: PEER's convention
    "ACCELERATION, GALWAY STATION": "g",  # 'GAL' inside a word is no unit
}
FACTOR = {"g": G_STANDARD, "cm/s2": 0.01, "m/s2": 1.0}


@pytest.mark.parametrize("line3", HEADER_FORMS)
def test_at2_header_units_in_their_common_forms(tmp_path, line3):
    head = NGA_HEAD.replace("ACCELERATION TIME SERIES IN UNITS OF G", line3)
    p = _write(tmp_path, "h.AT2", head + "NPTS= 2, DT= .01\n .5 -.25\n")
    want = HEADER_FORMS[line3]
    np.testing.assert_allclose(read_at2(p).acc_m_s2, np.array([0.5, -0.25]) * FACTOR[want], rtol=1e-15)
    np.testing.assert_allclose(read_at2(p, units=want).acc_m_s2, np.array([0.5, -0.25]) * FACTOR[want], rtol=1e-15)


def test_at2_units_contradicting_the_header_are_refused(tmp_path):
    """units = 'gal' on a record whose header says UNITS OF G was read as gal: 981 times too weak."""
    p = _write(tmp_path, "g.AT2", NGA_HEAD + "NPTS= 2, DT= .01\n .5 -.25\n")
    _raises(["g.AT2", "line 3", "units = 'gal'", "(cm/s2)", "'UNITS OF G'", "(g)"], read_at2, p, units="gal")
    cm = _write(tmp_path, "cm.AT2", NGA_HEAD.replace("OF G", "OF CM/S/S") + "NPTS= 2, DT= .01\n .5 -.25\n")
    _raises(["cm.AT2", "units = 'g'", "'CM/S/S'"], read_at2, cm, units="g")
    _raises(["cm.AT2", "units = 'm/s2'"], read_record, cm, units="m/s2")


@pytest.mark.parametrize(
    "line3, why",
    [
        ("ACCELERATION IN MM/S2", "not supported"),
        ("ACCELERATION IN FT/SEC/SEC", "not supported"),
        ("ACCELERATION IN G (1 G = 981 CM/S2)", "names two units"),
        ("ACCELERATION TIME SERIES IN UNITS OF FURLONGS", "unrecognised units 'FURLONGS'"),
    ],
)
def test_at2_headers_that_cannot_be_read_are_refused(tmp_path, line3, why):
    p = _write(
        tmp_path, "x.AT2", NGA_HEAD.replace("ACCELERATION TIME SERIES IN UNITS OF G", line3) + "NPTS= 1, DT= .01\n .1\n"
    )
    _raises(["x.AT2", "line 3", why], read_at2, p)


def test_trailing_blank_lines_are_fine(tmp_path):
    p = _write(tmp_path, "t.AT2", NGA_HEAD + "NPTS= 2, DT= .01 SEC\n .1E+00 .2E+00\n\n   \n\n")
    np.testing.assert_allclose(read_at2(p).acc_m_s2, [0.1 * G_STANDARD, 0.2 * G_STANDARD])


def _raises(match_parts, fn, *args, **kwargs) -> str:
    with pytest.raises(RecordError) as exc:
        fn(*args, **kwargs)
    msg = str(exc.value)
    for part in match_parts:
        assert part in msg, f"{part!r} not in {msg!r}"
    return msg


def test_at2_errors(tmp_path):
    missing = tmp_path / "nope.AT2"
    _raises(["nope.AT2", "cannot read"], read_at2, missing)

    short = _write(tmp_path, "short.AT2", "PEER NGA STRONG MOTION DATABASE RECORD\nx\n")
    _raises(["short.AT2", "2 line", "4 header lines"], read_at2, short)

    no_npts = _write(tmp_path, "nonpts.AT2", NGA_HEAD + "DT= .01 SEC\n .1 .2\n")
    _raises(["nonpts.AT2", "line 4", "NPTS"], read_at2, no_npts)

    no_dt = _write(tmp_path, "nodt.AT2", NGA_HEAD + "NPTS= 2\n .1 .2\n")
    msg = _raises(["nodt.AT2", "line 4", "DT"], read_at2, no_dt)
    assert "NPTS and" not in msg

    zero = _write(tmp_path, "zero.AT2", NGA_HEAD + "NPTS= 0, DT= .01\n")
    _raises(["zero.AT2", "NPTS", "'0'"], read_at2, zero)

    neg_dt = _write(tmp_path, "negdt.AT2", NGA_HEAD + "NPTS= 2, DT= -.01\n .1 .2\n")
    _raises(["negdt.AT2", "DT", "'-.01'"], read_at2, neg_dt)

    bad = _write(tmp_path, "bad.AT2", NGA_HEAD + "NPTS= 4, DT= .01\n .1 .2\n .3 1.2.3\n")
    _raises(["bad.AT2", "line 6", "'1.2.3'"], read_at2, bad)

    nan = _write(tmp_path, "nan.AT2", NGA_HEAD + "NPTS= 3, DT= .01\n .1\n .2 NaN\n")
    _raises(["nan.AT2", "line 6", "non-finite", "'NaN'"], read_at2, nan)

    few = _write(tmp_path, "few.AT2", NGA_HEAD + "NPTS= 5, DT= .01\n .1 .2 .3\n")
    _raises(["few.AT2", "found 3 values", "NPTS=5"], read_at2, few)

    many = _write(tmp_path, "many.AT2", NGA_HEAD + "NPTS= 2, DT= .01\n .1 .2\n\n .3\n")
    _raises(["many.AT2", "line 7", "more values than NPTS=2", "'.3'"], read_at2, many)

    ok = _write(tmp_path, "ok.AT2", NGA_HEAD + "NPTS= 1, DT= .01\n .1\n")
    _raises(["ok.AT2", "'furlongs'", "'g'", "'cm/s2'"], read_at2, ok, units="furlongs")

    vel = _write(
        tmp_path,
        "vel.AT2",
        NGA_HEAD.replace("ACCELERATION", "VELOCITY").replace("OF G", "OF CM/S") + "NPTS= 1, DT= .01\n .1\n",
    )
    _raises(["vel.AT2", "line 3", "not an acceleration"], read_at2, vel)


# --------------------------------------------------------------------------- CSV


def test_csv_header_t0_shift_and_units(tmp_path):
    p = _write(tmp_path, "rec.csv", "time_s,acc_cm_s2\n2.00,10\n2.02,-20\n2.04,30\n2.06,0\n")
    rec = read_csv_record(p, units="cm/s2")
    assert rec.name == "rec"
    assert rec.description == ""
    assert rec.dt_s == pytest.approx(0.02, rel=1e-12)
    np.testing.assert_allclose(rec.acc_m_s2, [0.1, -0.2, 0.3, 0.0], rtol=1e-15)
    assert rec.time_s[0] == 0.0
    assert rec.duration_s == pytest.approx(0.06)
    # whitespace and semicolon delimiters, no header, default units m/s2, via read_record
    p2 = _write(tmp_path, "rec.txt", "0.0  1.5\n0.1\t-2.5\n")
    r2 = read_record(p2)
    assert r2.acc_m_s2.tolist() == [1.5, -2.5] and r2.dt_s == pytest.approx(0.1)
    p3 = _write(tmp_path, "semi.csv", "0;0.1\n0.5;0.2\n1.0;0.3\n")
    r3 = read_record(p3, units="g")
    np.testing.assert_allclose(r3.acc_m_s2, np.array([0.1, 0.2, 0.3]) * G_STANDARD, rtol=1e-15)


def test_csv_step_from_the_end_stamps_and_their_written_precision(tmp_path):
    """The step comes from the first and last stamps (exact for stamps k dt correctly rounded, where the
    median of the differences is off by up to n u); stamps written with few decimals (300 Hz with 6
    decimals: each up to 5e-7 s off the grid) are accepted within one unit of their last place."""
    t = np.arange(5176) * 0.005
    exact = tmp_path / "exact.csv"
    np.savetxt(exact, np.column_stack([t, np.sin(t)]), delimiter=",", fmt="%.17g")
    assert read_csv_record(exact).dt_s == 0.005
    t300 = np.arange(3000) / 300
    six = _write(tmp_path, "six.csv", "t,a\n" + "".join(f"{x:.6f},{np.sin(x):.6f}\n" for x in t300))
    rec = read_csv_record(six)
    assert rec.dt_s == pytest.approx(1 / 300, abs=5e-7 / 2999)  # the last stamp's rounding (5e-7 s) over 2999 steps
    skipped = _write(tmp_path, "skip.csv", "t,a\n" + "".join(f"{x:.6f},0\n" for k, x in enumerate(t300) if k != 1500))
    _raises(["skip.csv", "line 1502", "non-uniform", "resample"], read_csv_record, skipped)


def test_csv_errors(tmp_path):
    unsorted = _write(tmp_path, "unsorted.csv", "t,a\n0.0,1\n0.1,2\n0.05,3\n")
    _raises(["unsorted.csv", "line 4", "strictly increasing", "0.05"], read_csv_record, unsorted)

    uneven = _write(tmp_path, "uneven.csv", "0.0,1\n0.1,2\n0.2,3\n0.31,4\n0.41,5\n")
    _raises(["uneven.csv", "line 4", "non-uniform", "resample"], read_csv_record, uneven)

    text = _write(tmp_path, "text.csv", "t,a\n0.0,1\n0.1,abc\n")
    _raises(["text.csv", "line 3", "'abc'"], read_csv_record, text)

    nan = _write(tmp_path, "nan.csv", "0.0,1\n0.1,nan\n")
    _raises(["nan.csv", "line 2", "non-finite"], read_csv_record, nan)

    one = _write(tmp_path, "one.csv", "t,a\n0.0,1\n")
    _raises(["one.csv", "at least 2"], read_csv_record, one)

    cols = _write(tmp_path, "cols.csv", "0.0,1,2\n0.1,2,3\n")
    _raises(["cols.csv", "line 1", "2 columns"], read_csv_record, cols)

    ok = _write(tmp_path, "ok.csv", "0.0,1\n0.1,2\n")
    _raises(["ok.csv", "'mm/s2'", "accepted"], read_csv_record, ok, units="mm/s2")
    _raises(["ok.csv", "'xyz'"], read_record, ok, format="xyz")
    _raises(["nope.csv", "cannot read"], read_csv_record, tmp_path / "nope.csv")
    _raises(["x.dat", "suffix"], read_record, tmp_path / "x.dat")


# --------------------------------------------------------------------------- similitude, resample


def _rec(acc, dt, description="event") -> GroundRecord:
    return GroundRecord(name="syn", source="syn.csv", dt_s=dt, acc_m_s2=np.asarray(acc, float), description=description)


def test_similitude_scale():
    rec = _rec([0.0, 1.0, -2.0, 0.5], 0.01)
    s = similitude_scale(rec, 15)
    assert s.dt_s == pytest.approx(0.01 / math.sqrt(15), rel=1e-15)
    assert np.array_equal(s.acc_m_s2, rec.acc_m_s2)
    assert s.pga_m_s2 == rec.pga_m_s2
    assert s.duration_s == pytest.approx(rec.duration_s / math.sqrt(15))
    assert s.name == "syn"
    assert s.description == "event [similitude 1/15: time / sqrt(15)]"
    assert rec.dt_s == 0.01  # original untouched
    for bad in (0, -2.0, float("nan"), float("inf")):
        _raises(["length_scale", repr(bad)], similitude_scale, rec, bad)


def test_resample_exact_linear_and_tail():
    acc = np.array([0.0, 2.0, -4.0, 1.0])
    rec = _rec(acc, 0.01)
    # same grid: exact copy
    same = resample(rec, 0.01)
    assert same.dtype == np.float64 and same.flags.c_contiguous
    assert np.array_equal(same, acc)
    # half step: originals at even indices, midpoints in between
    half = resample(rec, 0.005)
    assert half.size == 7
    assert np.array_equal(half[::2], acc)
    np.testing.assert_allclose(half[1::2], [1.0, -1.0, -1.5], rtol=0, atol=1e-12)
    # a quarter of the way into the 2nd interval: 2 + 0.25 * (-6) = 0.5
    q = resample(rec, 0.0025)
    assert q[5] == pytest.approx(0.5, abs=1e-12)
    # zero tail past the end, length floor(dur/dt + 1e-9) + 1
    long = resample(rec, 0.01, duration_s=0.1)
    assert long.size == 11
    assert np.array_equal(long[:4], acc)
    assert np.all(long[4:] == 0.0)
    # shorter duration truncates; duration that is not a multiple of dt rounds down
    assert resample(rec, 0.01, duration_s=0.015).tolist() == [0.0, 2.0]
    assert resample(rec, 0.007).size == math.floor(0.03 / 0.007 + 1e-9) + 1  # 5 samples
    # the last original sample survives round-off on a non-commensurate grid
    assert resample(rec, 0.03 / 7)[-1] == pytest.approx(1.0, abs=1e-9)
    for bad in (0.0, -0.01, float("nan"), float("inf")):
        _raises(["dt_s"], resample, rec, bad)
    _raises(["duration_s"], resample, rec, 0.01, -1.0)


def test_resample_real_record_on_original_grid(gm_dir):
    rec = read_at2(_gm_file(gm_dir, "RSN1605_DUZCE_DZC180.AT2"))
    out = resample(rec, rec.dt_s)
    assert np.array_equal(out, rec.acc_m_s2)
    scaled = similitude_scale(rec, 15)
    assert np.array_equal(resample(scaled, scaled.dt_s), rec.acc_m_s2)


def test_a_vertical_component_and_a_record_finer_than_the_step_are_named():
    """A helper's trial ran Bolu UP and Lamont 362 V as horizontal motions, and dt_s = 0.05 s over records sampled
    every 0.005 s (the required gap 10 % short), both without a word. The header's component names the first; a
    step above 1.5 record samples the second (the runs read the record at their steps, with no anti-alias filter)."""
    from types import SimpleNamespace

    from pounding_sweep.model.records import GroundRecord, similitude_scale, vertical_component
    from pounding_sweep.sweep.checks import check_motion
    from pounding_sweep.warn import collecting

    def rec(desc, dt=0.005):
        return GroundRecord(
            name="x", source=f"/r/{desc[-2:].strip()}.AT2", dt_s=dt, acc_m_s2=np.zeros(8), description=desc
        )

    up, east = rec("Duzce Turkey, 11/12/1999, Bolu, UP"), rec("Duzce Turkey, 11/12/1999, Lamont 362, E")
    assert vertical_component(up) == "UP" and vertical_component(similitude_scale(up, 15)) == "UP"
    assert vertical_component(rec("Duzce Turkey, 11/12/1999, Lamont 362, V")) == "V"
    assert vertical_component(east) is None and vertical_component(rec("no component here")) is None
    with collecting() as got:
        scene = SimpleNamespace(integration=SimpleNamespace(auto=False))
        check_motion(
            SimpleNamespace(scene=scene, excitation=SimpleNamespace(kind="record", dt=0.05, records=(up, east)))
        )
    kinds = {w.kind: w.message for w in got.items}
    assert "a vertical component (its header: 'Duzce Turkey, 11/12/1999, Bolu, UP')" in kinds["record_vertical"]
    assert "dt_s = 0.05 s steps over the samples of UP.AT2 (every 0.005 s), E.AT2" in kinds["record_step"]
    assert "use dt_s <= 0.005 s" in kinds["record_step"]
    with collecting() as got:
        check_motion(SimpleNamespace(scene=scene, excitation=SimpleNamespace(kind="record", dt=0.005, records=(east,))))
    assert not got.items
