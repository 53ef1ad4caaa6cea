"""The README's Python example runs as it is written, in a scratch folder."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from conftest import REPO


@pytest.mark.parametrize("readme", ["README.md", "python/README.md"])
def test_the_readme_python_examples_run(readme: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = (REPO / readme).read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert blocks, f"{readme} has no python example"
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        for block in blocks:
            exec(compile(block, readme, "exec"), {"__name__": "__readme__"})
    finally:
        os.chdir(cwd)
    assert "pump-0" in capsys.readouterr().out
