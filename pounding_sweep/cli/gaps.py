"""`python -m pounding_sweep gaps SCENE.toml`: a seismic-gap study of a scene (pounding_sweep.gaps): the
gap each floor pair needs under each of its records, exact and by ABS, SRSS, DDC and TBEC 2018's
minimum, and the response ratios adjacent / separated over a ladder of gaps.

Writes a folder (default results/<scene>.gaps/) holding required_gaps.parquet, response_ratios.parquet
(CSV copies beside them) and their PNG figures; prints both tables. Exit 0, or 2 with one `error:` line
on bad input (nothing written). A folder that already holds files of these names is written into only when
its required_gaps.parquet is a study's (its metadata says so): a user's file is never replaced. Every file is
made in memory first, then written under a hidden temporary name and renamed, the study's own Parquet table
first (so a folder with any new file is marked as the study's).
"""

from __future__ import annotations

import argparse
import io
import json
import math
import os
import sys
from pathlib import Path

from pounding_sweep.cli.common import EXIT_BAD_INPUT, Bad, OneLineParser, hidden_temporary, print_warning, split_list

#: the files a study writes into its folder, the one that marks the folder as a study's first
FILES = (
    "required_gaps.parquet",
    "response_ratios.parquet",
    "required_gaps.csv",
    "response_ratios.csv",
    "required_gaps.png",
    "response_ratios.png",
)


def _parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="python -m pounding_sweep gaps", description=__doc__.split("\n\n")[0])
    p.add_argument("scene", help="scene file (TOML); its records (or harmonic motion) and buildings are studied")
    p.add_argument("--out", help="output folder (default: <scene's output folder>/<scene name>.gaps)")
    p.add_argument(
        "--relative-gaps",
        help="gaps of the ratio runs over the required gap, comma-separated "
        "(default 0,0.05,0.1,0.2,0.3,0.5,0.7,0.85,1,1.2)",
    )
    p.add_argument(
        "--length-scale",
        type=float,
        help="similitude length scale to full scale (default: the scene's [excitation] length_scale)",
    )
    p.add_argument(
        "--ks-ratio", type=float, help="contact stiffness k_s / k_ref of the ratio runs (default: the scene's)"
    )
    p.add_argument("--r", type=float, help="coefficient of restitution of the ratio runs (default: the scene's)")
    p.add_argument("--threads", type=int, default=0, help="worker threads (0: all cores, at most 1024)")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    return p


def _positive_finite(value: float, option: str) -> None:
    if not (math.isfinite(value) and value > 0):
        raise Bad(option, "must be a finite number > 0", value)


def _check_options(args) -> list[float] | None:
    """Every option, before the scene runs: the relative gaps (finite, >= 0), the length scale, k_s/k_ref, r and
    the thread count."""
    from pounding_sweep.errors import InputError
    from pounding_sweep.scene.validate import check_workers

    rel = None
    if args.relative_gaps is not None and not split_list(args.relative_gaps):
        raise InputError(
            f"--relative-gaps {args.relative_gaps!r}: expected numbers separated by commas (omit the option for the "
            "default)"
        )
    if args.relative_gaps:
        try:
            rel = [float(x) for x in split_list(args.relative_gaps)]
        except ValueError:
            raise InputError(f"--relative-gaps {args.relative_gaps!r}: expected numbers separated by commas") from None
        if not rel or any(not (math.isfinite(x) and x >= 0) for x in rel):
            raise InputError(f"--relative-gaps {args.relative_gaps!r}: expected finite numbers >= 0")
        twice = sorted({x for x in rel if rel.count(x) > 1})
        if twice:
            raise InputError(f"--relative-gaps {args.relative_gaps!r}: {twice[0]:g} given twice")
    if args.length_scale is not None:
        _positive_finite(args.length_scale, "--length-scale")
    if args.r is not None and not 0 <= args.r <= 1:
        raise InputError(f"--r {args.r!r}: the coefficient of restitution must lie in [0, 1]")
    if args.ks_ratio is not None:
        _positive_finite(args.ks_ratio, "--ks-ratio")
    check_workers(args.threads, "--threads")
    return rel


def _study_table(path: Path) -> bool:
    """Whether `path` is a table a gap study wrote (its metadata says kind 'gap_study')."""
    try:
        import pyarrow.parquet as pq

        md = pq.read_metadata(path).metadata or {}
        return json.loads(md[b"pounding_sweep"]).get("kind") == "gap_study"
    except Exception:  # noqa: BLE001 - not Parquet, damaged, not ours: not shown to be the study's
        return False


def check_study_folder(out: Path) -> None:
    """Refuse (Bad) an output folder that is a file, or that holds a file of a study's names while it is not a
    study's folder (its required_gaps.parquet is not one a study wrote)."""
    if not (out.exists() or out.is_symlink()):
        return
    if not out.is_dir():
        raise Bad(
            out, "exists and is not a folder (the study writes a folder of tables and figures)", "give another --out"
        )
    taken = [name for name in FILES if (out / name).exists() or (out / name).is_symlink()]
    if taken and not ((out / FILES[0]).is_file() and _study_table(out / FILES[0])):
        raise Bad(
            out / taken[0],
            "exists and is not a file a gap study wrote; the study never replaces another file",
            "give another --out, or move it away",
        )


def gaps_main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    from pounding_sweep.errors import InputError
    from pounding_sweep.scene import load_scene

    try:
        rel = _check_options(args)
        scene = load_scene(args.scene)
        from pounding_sweep.scene.validate import require_two_buildings

        require_two_buildings(scene, "a seismic-gap study")
        out = Path(args.out) if args.out else Path(scene.output.path).with_name(f"{scene.name}.gaps")
        check_study_folder(out)
        from pounding_sweep.gaps import RELATIVE_GAPS, gap_study
        from pounding_sweep.warn import collecting

        with collecting(echo=print_warning):
            study = gap_study(
                scene, rel or RELATIVE_GAPS, args.length_scale, args.threads, ks_ratio=args.ks_ratio, r=args.r
            )
        write_study(study, scene, out)
    except (Bad, InputError) as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as e:
        print(
            f"error: {getattr(e, 'filename', None) or args.out}: cannot write the study ({e.strerror or e})",
            file=sys.stderr,
        )
        return EXIT_BAD_INPUT
    if not args.quiet:
        print_study(study, out, scene)
    return 0


def study_files(study, scene) -> dict[str, bytes]:
    """The study's tables (Parquet with the scene in the metadata, and CSV) and figures, by file name, in memory."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from pounding_sweep.gaps.figures import required_gap_figure, response_ratio_figure
    from pounding_sweep.gaps.study import COLUMN_DOCS
    from pounding_sweep.sweep.results import versions

    meta = {
        b"pounding_sweep": json.dumps(
            {
                **versions(),
                "kind": "gap_study",
                "scene_name": scene.name,
                "config_hash": scene.config_hash(),
                "length_scale": study.length_scale,
                "contact": study.contact,
                "columns": COLUMN_DOCS,
            }
        ).encode(),
        b"scene_toml": scene.toml_text.encode(),
    }
    files = {}
    for name, df in (("required_gaps", study.required), ("response_ratios", study.ratios)):
        buf = io.BytesIO()
        pq.write_table(pa.Table.from_pandas(df, preserve_index=False).replace_schema_metadata(meta), buf)
        files[f"{name}.parquet"] = buf.getvalue()
        files[f"{name}.csv"] = df.to_csv(index=False).encode()
    try:
        figures = {
            "required_gaps.png": required_gap_figure(study.required, f"{scene.name}: the gap each floor pair needs"),
            "response_ratios.png": response_ratio_figure(
                study.ratios, f"{scene.name}: response with a short gap / separated"
            ),
        }
    except SystemExit:  # no matplotlib: the tables are the study, the figures are optional
        figures = {}
    for name, fig in figures.items():
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=120)
        files[name] = buf.getvalue()
    return files


def write_study(study, scene, out: Path) -> None:
    """The study's files into `out`, each complete before it is renamed into place (study_files)."""
    files = study_files(study, scene)
    out.mkdir(parents=True, exist_ok=True)
    for name in FILES:
        if name not in files:
            continue
        path = out / name
        tmp = hidden_temporary(path)
        try:
            tmp.write_bytes(files[name])
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)


def _contact_text(study) -> str:
    """The contact of the ratio runs in words: its law and its stiffness and r, whichever form the law takes."""
    c = study.contact
    parts = [f"law {c['law']}"]
    for key, label in (
        ("ks_ratio", "k_s/k = {:g}"),
        ("ks_N_per_m", "k_s = {:g} N/m"),
        ("kh_N_per_m1_5", "k_h = {:g} N/m^1.5"),
    ):
        if c.get(key) is not None:
            parts.append(label.format(c[key]))
    if c.get("r") is not None:
        parts.append(f"r = {c['r']:g}")
    return "contact: " + ", ".join(parts)


def print_study(study, out: Path, scene=None) -> None:
    req = study.required
    lam = study.length_scale
    scale = f"model scale; x {lam:g} for full scale" if lam != 1 else "the scene's scale (length_scale = 1)"
    e = scene.excitation if scene is not None else None
    if e is not None and e.type == "record" and e.scaling == "intensity":  # which intensity the one run per record had
        scale += f"; each record at {'Sa' if e.intensity == 'sa' else 'PGA'} = {e.scale:g} g ([excitation] scale)"
    print(f"required gap per floor pair [mm, {scale}]:")
    cols = ["record", "pair", "exact_m", "abs_m", "srss_m", "ddc_m", "tbec2018_min_m"]
    show = req[cols].copy()
    for c in cols[2:]:
        show[c] = (show[c] * 1e3).round(3)
    show.columns = ["record", "pair", "exact", "ABS", "SRSS", "DDC", "TBEC min"]
    print(show.to_string(index=False))
    r = study.ratios
    print(f"\nresponse adjacent / separated ({_contact_text(study)}):")
    show = r[["record", "relative_gap", "building", "disp_ratio", "drift_ratio", "acc_ratio", "impacts"]]
    print(show.to_string(index=False, float_format=lambda x: f"{x:.3f}"))
    print(f"\nwritten: {out}")
