"""Execute examples/xarray_api.ipynb so that it cannot rot (its cells assert the correction)."""

from pathlib import Path

import ipykernel  # noqa: F401  (the kernel that runs the notebook: a test dependency)
import nbclient
import nbformat

NOTEBOOK = Path(__file__).resolve().parents[1] / "examples" / "xarray_api.ipynb"


def test_notebook_runs(tmp_path):
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(notebook, timeout=180, kernel_name="python3",
                                     resources={"metadata": {"path": str(tmp_path)}})
    client.execute()  # raises CellExecutionError with the cell and traceback on any failure
    text = "".join(output.get("text", "") for cell in notebook.cells if cell.cell_type == "code"
                   for output in cell.outputs)
    assert "east/west brightness" in text
    assert not any(output.output_type == "error" for cell in notebook.cells if cell.cell_type == "code"
                   for output in cell.outputs)
    # The figure shows as a picture, not as "<Figure size ...>".
    data = [output.get("data", {}) for cell in notebook.cells if cell.cell_type == "code" for output in cell.outputs]
    assert any("image/png" in item for item in data)
    assert not any("<Figure size" in item.get("text/plain", "") for item in data)
