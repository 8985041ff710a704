"""The README's Python quick starts run as written (each block in a fresh interpreter)."""
import re
from pathlib import Path

import pytest
from support.snippets import assert_snippet_runs

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_has_python_quick_starts():
    assert len(BLOCKS) >= 3


@pytest.mark.parametrize("i", range(len(BLOCKS)))
def test_readme_python_block_runs(i, tmp_path):
    assert_snippet_runs(BLOCKS[i], tmp_path)
