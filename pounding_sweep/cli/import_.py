"""`python -m pounding_sweep import NAME=FILE ... --out FOLDER`: raw per-sensor exports (one accelerometer per
floor and one on the table) -> an experiment table, the table's record and a provenance note
(model/sensors/assemble.py does the work; docs/how-to/import-real-sensor-data.md says how to use them in a scene).

Writes FOLDER/table.parquet (t_s and one `<NAME>_acc_m_s2` column per sensor; the import's findings in its
metadata), FOLDER/record.csv (the reference sensor's acceleration: t_s, acc_m_s2) and FOLDER/provenance.md.
A FOLDER that holds anything else than an earlier import's output is refused (nothing is overwritten that is
not provably ours). Exit status 0 when done, 2 with one line `error: ...` and nothing written on bad input.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
from pathlib import Path

from pounding_sweep.cli.common import EXIT_BAD_INPUT, Bad, OneLineParser, numbers

OUTPUTS = ("table.parquet", "record.csv", "provenance.md")


def _parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="python -m pounding_sweep import",
        description="Import raw sensor exports (one file per sensor, e.g. Xsens DOT CSV) into an experiment table "
        "and a record: the shaking axis, the clocks aligned (a shared device clock, else cross-correlation), one "
        "time grid, offsets (gravity's tilt projection) removed by the mean of a quiet window, signs made to "
        "agree with the table's; every step in provenance.md.",
    )
    p.add_argument("sensors", nargs="+", help="NAME=FILE per sensor, e.g. ground=g.csv b1f1=f1.csv b1f2=f2.csv")
    p.add_argument("--out", required=True, help="output folder (created; an earlier import's output is replaced)")
    p.add_argument("--reference", default="ground", help="the sensor on the shaking table (default: ground)")
    p.add_argument("--format", default="auto", help="file format (default: recognised from the file's head)")
    p.add_argument(
        "--axis",
        default="auto",
        help="every sensor's shaking axis: x, y or z, a horizontal one (default: each one's own)",
    )
    p.add_argument("--clock", default="auto", choices=["auto", "device", "xcorr"], help="how clocks are aligned")
    p.add_argument(
        "--quiet",
        help="START,END [s of the common span]: the window whose mean is the offset (default: the quietest 1 s)",
    )
    p.add_argument("--band", help="LO,HI [Hz]: band of sign and alignment (default: below half the first resonance)")
    p.add_argument("--max-lag", type=float, help="largest clock offset searched by cross-correlation [s]")
    return p


def _ours(folder: Path) -> bool:
    """True when `folder` holds nothing but an earlier import's output (its provenance note says so)."""
    names = {p.name for p in folder.iterdir()}
    if not names <= set(OUTPUTS) or "provenance.md" not in names:
        return False
    from pounding_sweep.model.sensors.assemble import PROVENANCE_HEAD

    try:
        return (folder / "provenance.md").read_text(encoding="utf-8").startswith(PROVENANCE_HEAD)
    except (OSError, UnicodeDecodeError):
        return False


def import_main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    from pounding_sweep.errors import InputError

    try:
        files = {}
        for s in args.sensors:
            name, eq, path = s.partition("=")
            if not eq or not name or not path:
                raise Bad(s, "a sensor is NAME=FILE", "e.g. ground=ground.csv")
            if not name.replace("_", "").isalnum():
                raise Bad(s, f"sensor name {name!r} must be letters, digits and _ (it names a table column)")
            if name in files:
                raise Bad(s, f"sensor {name!r} given twice")
            files[name] = path
        out = Path(args.out)
        if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not _ours(out))):
            raise Bad(out, "exists and is not an earlier import's output: choose another --out", "nothing written")
        try:
            quiet = tuple(numbers(args.quiet, 2, "--quiet")) if args.quiet else None
            band = tuple(numbers(args.band, 2, "--band")) if args.band else None
        except ValueError as e:
            raise Bad(args.quiet if "quiet" in str(e) else args.band, str(e)) from None
        if quiet is not None and not quiet[0] < quiet[1]:
            raise Bad("--quiet", "START must be below END", args.quiet)
        if band is not None and not 0 < band[0] < band[1]:
            raise Bad("--band", "0 < LO < HI needed", args.band)
        from pounding_sweep.model.sensors.assemble import import_sensors, provenance_text

        im = import_sensors(files, args.reference, args.format, args.axis, args.clock, quiet, band, args.max_lag)
        for w in im.warnings:
            print(f"warning: {w}", file=sys.stderr)
        command = "python -m pounding_sweep import " + " ".join(shlex.quote(a) for a in argv)
        _write(out, im, provenance_text(im, command))
    except (Bad, InputError) as e:
        sys.stdout.flush()
        print(f"error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    _summary(im, out)
    return 0


def _write(out: Path, im, note: str) -> None:
    """The three files, each written to a .tmp and renamed: a failed import leaves no half file."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from pounding_sweep import __version__

    cols = {"t_s": im.time_s, **im.columns}
    meta = {
        "sensor_import": json.dumps({"settings": im.settings, "sensors": im.sensors}, default=float),
        "column_kinds": json.dumps({c: "acceleration" for c in im.columns}),
        "column_units": json.dumps({"t_s": "s", **{c: "m/s^2" for c in im.columns}}),
        "noise": json.dumps({c: im.sensors[c.removesuffix("_acc_m_s2")]["noise_m_s2"] for c in im.columns}),
        "provenance": note,
        "pounding_sweep_version": __version__,
    }
    table = pa.table(cols).replace_schema_metadata({k: v.encode() for k, v in meta.items()})
    ref = im.columns[im.column(im.reference)]
    dt = im.dt_s
    record = "t_s,acc_m_s2\n" + "".join(f"{k * dt:.9f},{a:.9g}\n" for k, a in zip(range(ref.size), np.asarray(ref)))
    made = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        tmps = []
        for name in OUTPUTS:
            tmp = out / f"{name}.tmp"
            tmps.append(tmp)
            if name == "table.parquet":
                pq.write_table(table, tmp)
            else:
                tmp.write_text(record if name == "record.csv" else note, encoding="utf-8")
        for name, tmp in zip(OUTPUTS, tmps):
            os.replace(tmp, out / name)
    except OSError as e:
        for name in OUTPUTS:
            (out / f"{name}.tmp").unlink(missing_ok=True)
        if made and out.exists() and not any(out.iterdir()):
            out.rmdir()
        raise Bad(out, "cannot write", e.strerror or e) from None


def _summary(im, out: Path) -> None:
    from pounding_sweep.scene.channels import building_floor

    print("\n".join(im.summary()))
    others = [n for n in im.sensors if n != im.reference]
    floors = [n for n in others if building_floor(n, bare=True)]
    chans = ", ".join(f'{im.column(n)} = "abs_acc_{n}"' for n in floors)
    unnamed = [n for n in others if n not in floors]
    q0, q1 = im.settings["quiet_s"]
    print(
        f"written: {out}/table.parquet, {out}/record.csv, {out}/provenance.md\n"
        "in a scene (floor sensors named b<building>f<floor>"
        + (f"; {', '.join(unnamed)} not so named: not a channel" if unnamed else "")
        + "):\n"
        f'  [excitation] type = "record"; record = "{out}/record.csv"; units = "m/s2"'
        + (
            f'\n  [experiment] table = "{out}/table.parquet"; acc_units = "m/s2"; channels = {{ {chans} }}; '
            f"noise_window_s = [{q0:.3f}, {q1:.3f}]   # the quiet window: each channel's noise"
            if floors
            else ""
        )
    )
