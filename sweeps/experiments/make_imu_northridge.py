"""Regenerate the shipped REAL experiment imu_northridge/ (the walkthrough docs/tutorials/real-shake-table.md).

Usage, from the repository root, with ../shared beside it:  python sweeps/experiments/make_imu_northridge.py

The Northridge test of the stiff 3-story model (../shared/data/imu_shake_table/stiff_3story/northridge: one
Xsens DOT IMU on the table and one per floor, 120 Hz, a shared device clock; BSD 2-Clause, chrystalchern/mdof)
imported by `python -m pounding_sweep import` exactly as a user would, then trimmed to TRIM_S of the import's
time grid: the quiet lead-in (the import's quiet window, where each sensor's noise is measured), the first two
bursts of shaking and the free decay between them. Not decimated: the model's third mode (about 40 Hz) needs the
120 Hz rate (decimating by 2 would fold it onto 20 Hz). The trimmed table keeps the import's Parquet metadata
(column kinds and units, each channel's noise, the provenance note with the trim added); the record is the
table's own column.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
OUT = HERE / "imu_northridge"
SOURCE = Path("..") / "shared" / "data" / "imu_shake_table"  # relative to the repository root, as the note says
TEST = SOURCE / "stiff_3story" / "northridge"
SENSORS = {"ground": "ground.csv", "b1f1": "floor1.csv", "b1f2": "floor2.csv", "b1f3": "floor3.csv"}
#: [start, end) of the import's time grid kept [s]: 8 s (the table still: the quiet window 8.71-9.70 s lies in
#: it) to 28 s (after the second burst); written from t_s = 0
TRIM_S = (8.0, 28.0)


def trim_note(n: int, dt: float, quiet: list[float]) -> str:
    lo, hi = TRIM_S
    return (
        f"\n## Trimmed for shipping (sweeps/experiments/make_imu_northridge.py)\n\n"
        f"Rows with {lo:g} s <= t_s < {hi:g} s of the import above kept ({n} samples, {n * dt:.3f} s at "
        f"{1.0 / dt:.3f} Hz), t_s and the record's time written from 0 (so the import's quiet window "
        f"{quiet[0] - lo:.3f}-{quiet[1] - lo:.3f} s here); no resampling, no filtering: the values are the import's.\n"
    )


def main() -> int:
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from pounding_sweep.cli.import_ import import_main

    if not (REPO / TEST).is_dir():
        print(f"error: {REPO / TEST}: not found (the ../shared data set beside the repository)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        full = Path(tmp) / "import"
        args = [f"{name}={(TEST / f).as_posix()}" for name, f in SENSORS.items()] + ["--out", str(full)]
        cwd = Path.cwd()
        try:  # the provenance names the files as the command gave them: relative to the repository root
            os.chdir(REPO)
            code = import_main(args)
        finally:
            os.chdir(cwd)
        if code:
            return code
        table = pq.read_table(full / "table.parquet")
        meta = dict(table.schema.metadata)
        t = table.column("t_s").to_numpy()
        keep = np.flatnonzero((t >= TRIM_S[0]) & (t < TRIM_S[1]))
        dt = float(np.median(np.diff(t)))
        cut = table.take(pa.array(keep))
        cols = {name: cut.column(name).to_numpy() for name in cut.column_names}
        cols["t_s"] = cols["t_s"] - cols["t_s"][0]
        imported = json.loads(meta[b"sensor_import"])
        note = meta[b"provenance"].decode().replace(str(full), "(a temporary folder)")
        note += trim_note(keep.size, dt, imported["settings"]["quiet_s"])
        imported["settings"]["trim_s"] = list(TRIM_S)
        meta[b"provenance"] = note.encode()
        meta[b"sensor_import"] = json.dumps(imported, default=float).encode()
        OUT.mkdir(exist_ok=True)
        pq.write_table(pa.table(cols).replace_schema_metadata(meta), OUT / "table.parquet")
        ref = cols["ground_acc_m_s2"]
        record = "t_s,acc_m_s2\n" + "".join(f"{k * dt:.9f},{a:.9g}\n" for k, a in enumerate(ref))
        (OUT / "record.csv").write_text(record, encoding="utf-8")
        (OUT / "PROVENANCE.md").write_text(provenance(note), encoding="utf-8")
        shutil.copyfile(REPO / SOURCE / "LICENSE_mdof.txt", OUT / "LICENSE_mdof.txt")
    print(f"wrote {OUT}: {keep.size} samples ({keep.size * dt:.2f} s), table.parquet, record.csv, PROVENANCE.md")
    return 0


def provenance(note: str) -> str:
    return (
        "# imu_northridge: a REAL shake-table test (not made by this project)\n\n"
        "**Source.** The stiff 3-story model's Northridge test, one Xsens DOT IMU on the shaking table and one on "
        "each floor (about 120 Hz, one shared device clock), from the repository chrystalchern/mdof, commit "
        "4f0e831cae79a1c021bd4081e9d952c0f6f6e3b4, folder `notebooks/uploads/mini_shake_table/Flexible vs. "
        "Stiff/Stiff 3 story/` (files `(Northridge)...` of its `Ground Floor`, `1st Floor`, `2nd Floor` and "
        "`3rd Floor (Top floor)` folders), as copied into ../shared/data/imu_shake_table/stiff_3story/northridge.\n\n"
        "**Licence.** BSD 2-Clause, copyright (c) 2023 Chrystal Chern: `LICENSE_mdof.txt` beside this file travels "
        "with the data.\n\n"
        "**Files.** `table.parquet`: `t_s` (s) and each sensor's absolute acceleration along the shaking axis "
        "(`ground_acc_m_s2` the table, `b1f1..3_acc_m_s2` the floors, m/s^2); its metadata holds everything below. "
        "`record.csv`: the table's column as a record (`t_s,acc_m_s2`). Regenerate both with "
        "`python sweeps/experiments/make_imu_northridge.py` (needs ../shared).\n\n"
        "What the import found and did, then the trim:\n\n" + note.replace("# Imported by", "### Imported by", 1)
    )


if __name__ == "__main__":
    sys.exit(main())
