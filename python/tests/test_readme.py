"""The README's Python example runs as written, on the installed package."""

import pathlib
import re

README = pathlib.Path(__file__).resolve().parents[2] / "README.md"


def test_readme_python_blocks_run():
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
    assert blocks, "the README lost its Python example"
    for code in blocks:
        scope = {}
        exec(compile(code, "README.md", "exec"), scope)
        # The example steps an environment: it must have produced an observation.
        assert "obs" in scope and "rgb" in scope["obs"]
