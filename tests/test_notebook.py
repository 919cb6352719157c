"""The analysis notebook runs top to bottom (nbclient) on the shipped scored 6 Hz sweep, in a kernel of
this interpreter, and shows its figures and tables; the committed notebook carries no outputs."""

from __future__ import annotations

import json
import sys

import pytest
from conftest import REPO
from gates import SAFETY_S

nbformat = pytest.importorskip("nbformat", reason="the notebook test needs the 'notebook' or 'test' extra")
nbclient = pytest.importorskip("nbclient", reason="the notebook test needs the 'notebook' or 'test' extra")
pytest.importorskip("ipykernel", reason="the notebook test needs the 'notebook' or 'test' extra")
pytest.importorskip("matplotlib", reason="the notebook test needs the 'notebook' or 'test' extra")

NOTEBOOK = REPO / "notebooks" / "analysis.ipynb"
KERNEL = "pounding-sweep-test"
FIGURES = 8  # heatmaps, displacement history, SSP, pounding force, error against run time; risk: P vs gap, fragility, required gap


def _kernel_manager(tmp_path):
    """A kernel manager whose only kernelspec runs ipykernel on this interpreter (not whatever 'python3'
    a user or system kernelspec names)."""
    from jupyter_client.kernelspec import KernelSpecManager
    from jupyter_client.manager import AsyncKernelManager

    spec = tmp_path / "kernels" / KERNEL
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(
        json.dumps(
            {
                "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
                "display_name": "pounding_sweep test",
                "language": "python",
            }
        )
    )
    ksm = KernelSpecManager(kernel_dirs=[str(tmp_path / "kernels")], ensure_native_kernel=False)
    return AsyncKernelManager(kernel_name=KERNEL, kernel_spec_manager=ksm)


def _with_parameters(nb, **params):
    """Insert a cell setting `params` after the cell tagged 'parameters' (as papermill does)."""
    (i,) = [k for k, c in enumerate(nb.cells) if "parameters" in c.metadata.get("tags", [])]
    src = "\n".join(f"{k} = {v!r}" for k, v in params.items())
    nb.cells.insert(i + 1, nbformat.v4.new_code_cell(src, metadata={"tags": ["injected-parameters"]}))
    return nb


CHECKS = """
import json, sys
print("CHECKS " + json.dumps({
    "executable": sys.executable, "results": str(results), "runs": len(df),
    "error_tables": {c: [list(plots.error_table(df, c).index), list(plots.error_table(df, c).columns)] for c in codes},
    "table4_rows": [list(i) for i in table4.index], "table4_columns": len(table4.columns),
    "schemes": sorted(set(accuracy.scheme)), "accuracy_rows": len(accuracy)}))
"""


def test_notebook_runs_top_to_bottom(tmp_path):
    nb = nbformat.read(NOTEBOOK, as_version=4)
    missing = tmp_path / "not_there.parquet"  # a missing result file: the notebook runs the shipped scene
    nb = _with_parameters(
        nb, RESULTS=str(missing), WORK_DIR=str(tmp_path / "work"), SCENE=str(REPO / "sweeps" / "scored_6hz.toml")
    )  # found also from a non-editable install
    nb.cells.append(nbformat.v4.new_code_cell(CHECKS))
    # every timeout a safety net (the whole notebook takes about 15 s warm): nbclient's defaults give the kernel
    # 60 s to start and a cell's output 4 s after its reply, then drop that output without an error (a loaded
    # machine would lose a figure); here a late output waits, and one that never comes is an error
    nbclient.NotebookClient(
        nb,
        km=_kernel_manager(tmp_path),
        timeout=SAFETY_S,
        startup_timeout=SAFETY_S,
        iopub_timeout=SAFETY_S,
        raise_on_iopub_timeout=True,
        resources={"metadata": {"path": str(tmp_path)}},
    ).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.output_type == "error"]
    images = [
        o for o in outputs if o.output_type in ("display_data", "execute_result") and "image/png" in o.get("data", {})
    ]
    assert len(images) == FIGURES, [c.source[:60] for c in nb.cells]
    tables = [o for o in outputs if "text/html" in o.get("data", {}) and "<table" in o.data["text/html"]]
    assert len(tables) >= 6  # facts, statuses, 2 error tables, best runs, Table 4, accuracy
    (line,) = [
        ln for o in outputs if o.output_type == "stream" for ln in o.text.splitlines() if ln.startswith("CHECKS ")
    ]
    checks = json.loads(line.removeprefix("CHECKS "))
    assert checks["executable"] == sys.executable
    assert checks["results"] == str(tmp_path / "work" / "scored_6hz.parquet") and checks["runs"] == 20
    assert not missing.exists()
    grid = [[0.1, 1.0, 5.0, 10.0], [0.2, 0.4, 0.6, 0.8, 1.0]]
    assert checks["error_tables"] == {"b1f3": grid, "b2f3": grid}
    assert checks["table4_rows"] == [[k, r] for k in grid[0] for r in grid[1]]  # (k_s/k, r)
    assert checks["table4_columns"] == 2 * 2  # per channel: Disp. [mm], Diff. [%]
    assert "implicit" in checks["schemes"] and checks["accuracy_rows"] == 5 * len(checks["schemes"])


def test_committed_notebook_is_clean():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(nb)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code and all(not c.outputs and c.execution_count is None for c in code), (
        "clear the outputs before committing"
    )
    assert sum("parameters" in c.metadata.get("tags", []) for c in code) == 1
