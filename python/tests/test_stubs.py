"""The type stubs of the compiled module (`sage3d/_sage3d.pyi`) match the built module: mypy's
stubtest finds every public name, parameter (names, kinds, defaults) and class member of
`sage3d._sage3d` in the stub and nothing in the stub that the module lacks. Nothing is
allowlisted."""

import os
import pathlib
import subprocess
import sys

import pytest

pytest.importorskip("mypy.stubtest", reason="mypy is not installed (pip install -r python/requirements-test.txt)")

REPO = pathlib.Path(__file__).resolve().parents[2]
STUB = REPO / "crates" / "sage-py" / "python" / "sage3d" / "_sage3d.pyi"


def test_stub_matches_the_compiled_module(tmp_path):
    # The stub alone, in a package of its own: with the source package on the path, stubtest
    # would type-check `sage3d/__init__.py` and the modules it imports first, and stop at any
    # mypy error there (torch not installed, ...) before looking at the stub.
    package = tmp_path / "stubs" / "sage3d"
    package.mkdir(parents=True)
    (package / "__init__.pyi").write_text("")
    (package / "_sage3d.pyi").write_text(STUB.read_text())
    # An empty configuration: no user or project mypy settings change the check.
    config = tmp_path / "mypy.ini"
    config.write_text("[mypy]\n")
    proc = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "sage3d._sage3d", "--mypy-config-file", str(config)],
        cwd=tmp_path,
        env={**os.environ, "MYPYPATH": str(tmp_path / "stubs")},
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, f"stubtest found differences:\n{proc.stdout}{proc.stderr}"
