"""Regenerate the shipped REAL experiment imu_bonus_event/ (sweeps/real_bonus_event.toml; the walkthrough
docs/tutorials/real-shake-table.md).

Usage, from the repository root, with ../shared beside it:  python sweeps/experiments/make_imu_bonus_event.py

The Bonus Event test of the stiff 3-story model (../shared/data/imu_shake_table/stiff_3story/bonus_event: one Xsens
DOT IMU on the table and one per floor, 120 Hz; BSD 2-Clause, chrystalchern/mdof), whose sensors' clocks are NOT
synchronised, imported by `python -m pounding_sweep import` exactly as a user would: the floors aligned to the
table by cross-correlation, every sample kept (22.4 s, 2687 samples: no trim is needed to keep it small). Then
`python -m pounding_sweep identify --modes-out` on the imported table writes modes.toml, the scene's start values.

FLOORS SWAPPED: the files `floor1.csv` and `floor2.csv` are imported as floors 2 and 1. Filed as they are, the
identified mode shapes (top floor 1) are mode 1 (0.82, 0.43, 1), mode 2 (-0.43, -1.09, 1), mode 3 (-1.93, 1.33, 1):
each is a 3-story shear frame's shape (and the Northridge test's, whose sensors share one clock: (0.42, 0.83, 1),
(-1.26, -0.31, 1), (1.02, -1.49, 1)) with its first two entries exchanged, and identify says so ("does not grow
with height ... are two floors' files swapped?"). Calibrated as filed, the frame misfits more (per-story stiffness
and modal damping: 60.6 times the sensors' noise, story 2 driven to its bound 3.0; swapped: 45.9, the stories
stiff / soft / stiff as in the Northridge fit). An independent estimate agrees: scipy's Welch H1 (table ->
floor, 1024-sample segments) peaks at 8.09 Hz at 35.6 (floor1.csv), 18.6 (floor2.csv), 43.3 (floor3.csv): the
file filed as floor 1 moves twice the one filed as floor 2 in the first mode (Northridge: 11.7, 22.1, 26.5). The
source's folders and the sensors' device tags (secondfloor, thirdfloor, topfloor) say otherwise; the motion says
this, and the PROVENANCE note records both.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
OUT = HERE / "imu_bonus_event"
SOURCE = Path("..") / "shared" / "data" / "imu_shake_table"  # relative to the repository root, as the note says
TEST = SOURCE / "stiff_3story" / "bonus_event"
#: model floor -> the file imported as it (floor1.csv and floor2.csv exchanged: module docstring)
SENSORS = {"ground": "ground.csv", "b1f1": "floor2.csv", "b1f2": "floor1.csv", "b1f3": "floor3.csv"}


def main() -> int:
    import pyarrow.parquet as pq

    if not (REPO / TEST).is_dir():
        print(f"error: {REPO / TEST}: not found (the ../shared data set beside the repository)", file=sys.stderr)
        return 2

    def command(*args: str) -> int:  # as a user types it, from the repository root (the provenance's paths)
        return subprocess.run([sys.executable, "-m", "pounding_sweep", *args], cwd=REPO).returncode

    with tempfile.TemporaryDirectory() as tmp:
        full = Path(tmp) / "import"
        code = command(
            "import", *[f"{name}={(TEST / f).as_posix()}" for name, f in SENSORS.items()], "--out", str(full)
        )
        if code:
            return code
        OUT.mkdir(exist_ok=True)
        shutil.copyfile(full / "record.csv", OUT / "record.csv")
        table = pq.read_table(full / "table.parquet")  # its metadata without the temporary folder's name
        meta = {k: v.replace(str(full).encode(), b"(a temporary folder)") for k, v in table.schema.metadata.items()}
        pq.write_table(table.replace_schema_metadata(meta), OUT / "table.parquet")
        note = (full / "provenance.md").read_text(encoding="utf-8").replace(str(full), "(a temporary folder)")
    (OUT / "PROVENANCE.md").write_text(provenance(note), encoding="utf-8")
    shutil.copyfile(REPO / SOURCE / "LICENSE_mdof.txt", OUT / "LICENSE_mdof.txt")
    code = command("identify", str((OUT / "table.parquet").relative_to(REPO)), "--modes-out", str(OUT / "modes.toml"))
    if code:
        return code
    print(f"wrote {OUT}: table.parquet, record.csv, PROVENANCE.md, modes.toml")
    return 0


def provenance(note: str) -> str:
    return (
        "# imu_bonus_event: a REAL shake-table test (not made by this project)\n\n"
        "**Source.** The stiff 3-story model's Bonus Event test, one Xsens DOT IMU on the shaking table and one on "
        "each floor (about 120 Hz; the sensors' clocks NOT synchronised), from the repository chrystalchern/mdof, "
        "commit 4f0e831cae79a1c021bd4081e9d952c0f6f6e3b4, folder `notebooks/uploads/mini_shake_table/Flexible vs. "
        "Stiff/Stiff 3 story/` (files `(Bonus Event)...` of its `Ground Floor`, `1st Floor`, `2nd Floor` and "
        "`3rd Floor (Top floor)` folders), as copied into ../shared/data/imu_shake_table/stiff_3story/bonus_event.\n\n"
        "**Licence.** BSD 2-Clause, copyright (c) 2023 Chrystal Chern: `LICENSE_mdof.txt` beside this file travels "
        "with the data.\n\n"
        "**Floors 1 and 2 exchanged.** `floor2.csv` (the source's `2nd Floor` folder) is imported as floor 1 "
        "(`b1f1`) and `floor1.csv` (`1st Floor`) as floor 2 (`b1f2`): filed as they are, every identified mode "
        "shape is a shear frame's (and the Northridge test's) with floors 1 and 2 exchanged (in the first mode the "
        "file filed as floor 1 moves twice the one filed as floor 2), and the per-story fit misfits more (60.6 "
        "against 45.9 times the sensors' noise). The source's folders and the device tags (secondfloor, thirdfloor) "
        "say the files are as filed; the motion says otherwise. sweeps/experiments/make_imu_bonus_event.py gives "
        "the numbers.\n\n"
        "**Files** (as imu_northridge/ holds them): `table.parquet`, the sensors' absolute accelerations along the "
        "shaking axis in m/s^2 with everything below in its metadata; `record.csv`, the table's column as a record; "
        "`modes.toml`, the modes `python -m pounding_sweep identify table.parquet --modes-out modes.toml` finds (a "
        "calibration's start values: [calibrate] start_from). `python sweeps/experiments/make_imu_bonus_event.py` "
        "regenerates them (it needs ../shared).\n\n"
        "What the import found and did:\n\n" + note.replace("# Imported by", "### Imported by", 1)
    )


if __name__ == "__main__":
    sys.exit(main())
