"""The package's pure-Python modules type-check: mypy finds no error in `sage3d/` (its modules
and the stub of the compiled module they import), with the settings the repository gives mypy
(none: mypy's defaults). Optional imports (torch, tqdm) must type-check whether or not they are
installed."""

import pathlib
import subprocess
import sys

import pytest

pytest.importorskip("mypy", reason="mypy is not installed (pip install -r python/requirements-test.txt)")

REPO = pathlib.Path(__file__).resolve().parents[2]
PACKAGE = REPO / "crates" / "sage-py" / "python" / "sage3d"


def test_mypy_finds_no_error_in_the_package(tmp_path):
    proc = subprocess.run(
        # From the repository root, so that a configuration there applies; the cache goes to a
        # temporary folder, not into the checkout.
        [sys.executable, "-m", "mypy", "--cache-dir", str(tmp_path / "cache"),
         str(PACKAGE.relative_to(REPO))],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, f"mypy found errors:\n{proc.stdout}{proc.stderr}"
