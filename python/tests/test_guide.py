"""The Python code of docs/guide/*.md runs as written."""

import pathlib
import re

import pytest

GUIDE = pathlib.Path(__file__).resolve().parents[2] / "docs" / "guide"
BLOCKS = [
    pytest.param(code, id=f"{page.name}:{n}")
    for page in sorted(GUIDE.glob("*.md"))
    for n, code in enumerate(re.findall(r"```python\n(.*?)```", page.read_text(), re.S))
]


def test_the_guide_has_python_code():
    assert BLOCKS, "docs/guide/*.md has python blocks"


@pytest.mark.parametrize("code", BLOCKS)
def test_guide_python_block_runs(code):
    exec(compile(code, "<guide>", "exec"), {"__name__": "__guide__"})
