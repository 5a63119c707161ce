"""The examples of docs/python.md run as written: every ```python block, in order, in one
namespace, from the repository root (as the page says)."""
import os
import re

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
DOC = os.path.join(ROOT, "docs", "python.md")


def python_blocks():
    with open(DOC, encoding="utf-8") as f:
        text = f.read()
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_docs_python_md_examples_run(monkeypatch, capsys):
    blocks = python_blocks()
    assert len(blocks) >= 4
    monkeypatch.chdir(ROOT)
    namespace = {"__name__": "__docs__"}
    for k, block in enumerate(blocks):
        try:
            exec(compile(block, "%s, block %d" % (DOC, k + 1), "exec"), namespace)
        except Exception as e:  # name the block that failed
            pytest.fail("docs/python.md block %d failed: %r\n%s" % (k + 1, e, block))
    out = capsys.readouterr().out
    assert "CarveConfig(voxel_size=0.01" in out
    assert re.search(r"carve: \d+ points in [\d.]+ s, median error [\d.]+ mm", out)
