"""`python -m pounding_sweep gaps SCENE.toml`: a seismic-gap study of a scene (pounding_sweep.gaps): the
gap each floor pair needs under each of its records, exact and by ABS, SRSS, DDC and TBEC 2018's
minimum, and the response ratios adjacent / separated over a ladder of gaps.

Writes a folder (default results/<scene>.gaps/) holding required_gaps.parquet, response_ratios.parquet
(CSV copies beside them) and their PNG figures; prints both tables. Exit 0, or 2 with one `error:` line
on bad input (nothing written).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from pounding_sweep.cli.common import EXIT_BAD_INPUT, split_list


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m pounding_sweep gaps", description=__doc__.split("\n\n")[0])
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
    p.add_argument("--threads", type=int, default=0, help="worker threads (0: all cores)")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    return p


def gaps_main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    from pounding_sweep.errors import InputError
    from pounding_sweep.scene import load_scene

    try:
        scene = load_scene(args.scene)
        rel = None
        if args.relative_gaps:
            try:
                rel = [float(x) for x in split_list(args.relative_gaps)]
            except ValueError:
                raise InputError(
                    f"--relative-gaps {args.relative_gaps!r}: expected numbers separated by commas"
                ) from None
            if not rel or any(not (x >= 0) for x in rel):
                raise InputError(f"--relative-gaps {args.relative_gaps!r}: expected numbers >= 0")
        if args.length_scale is not None and not args.length_scale > 0:
            raise InputError(f"--length-scale {args.length_scale!r}: must be > 0")
        if args.r is not None and not 0 <= args.r <= 1:
            raise InputError(f"--r {args.r!r}: the coefficient of restitution must lie in [0, 1]")
        if args.ks_ratio is not None and not args.ks_ratio > 0:
            raise InputError(f"--ks-ratio {args.ks_ratio!r}: must be > 0")
        out = Path(args.out) if args.out else Path(scene.output.path).with_name(f"{scene.name}.gaps")
        from pounding_sweep.gaps import RELATIVE_GAPS, gap_study

        study = gap_study(
            scene, rel or RELATIVE_GAPS, args.length_scale, args.threads, ks_ratio=args.ks_ratio, r=args.r
        )
        write_study(study, scene, out)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as e:
        print(
            f"error: {getattr(e, 'filename', None) or args.out}: cannot write the study ({e.strerror or e})",
            file=sys.stderr,
        )
        return EXIT_BAD_INPUT
    if not args.quiet:
        print_study(study, out)
    return 0


def write_study(study, scene, out: Path) -> None:
    """The study's tables (Parquet with the scene in the metadata, and CSV) and figures, into `out`."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from pounding_sweep.gaps.figures import required_gap_figure, response_ratio_figure

    out.mkdir(parents=True, exist_ok=True)
    meta = {
        b"pounding_sweep": json.dumps(
            {
                "kind": "gap_study",
                "scene_name": scene.name,
                "config_hash": scene.config_hash(),
                "length_scale": study.length_scale,
                "contact": study.contact,
            }
        ).encode(),
        b"scene_toml": scene.toml_text.encode(),
    }
    for name, df in (("required_gaps", study.required), ("response_ratios", study.ratios)):
        t = pa.Table.from_pandas(df, preserve_index=False).replace_schema_metadata(meta)
        pq.write_table(t, out / f"{name}.parquet")
        df.to_csv(out / f"{name}.csv", index=False)
    try:
        required_gap_figure(study.required, f"{scene.name}: the gap each floor pair needs").savefig(
            out / "required_gaps.png", dpi=120
        )
        response_ratio_figure(study.ratios, f"{scene.name}: response with a short gap / separated").savefig(
            out / "response_ratios.png", dpi=120
        )
    except SystemExit:  # no matplotlib: the tables are the study, the figures are optional
        pass


def print_study(study, out: Path) -> None:
    req = study.required
    lam = study.length_scale
    print(f"required gap per floor pair [mm, model scale{f'; x {lam:g} for full scale' if lam != 1 else ''}]:")
    cols = ["record", "pair", "exact_m", "abs_m", "srss_m", "ddc_m", "tbec2018_min_m"]
    show = req[cols].copy()
    for c in cols[2:]:
        show[c] = (show[c] * 1e3).round(3)
    show.columns = ["record", "pair", "exact", "ABS", "SRSS", "DDC", "TBEC min"]
    print(show.to_string(index=False))
    r = study.ratios
    print(f"\nresponse adjacent / separated (contact {study.contact or 'as in the scene'}):")
    show = r[["record", "relative_gap", "building", "disp_ratio", "drift_ratio", "acc_ratio", "impacts"]]
    print(show.to_string(index=False, float_format=lambda x: f"{x:.3f}"))
    print(f"\nwritten: {out}")
