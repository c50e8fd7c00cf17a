"""Every script in benchmarks/ and scripts/ compiles (a script's main is not imported by
the other tests; a syntax error there would otherwise surface only when someone runs it)."""

from __future__ import annotations

import py_compile

import pytest
from conftest import REPO

SCRIPTS = sorted(p for folder in ("benchmarks", "scripts") for p in (REPO / folder).rglob("*.py"))


def test_there_are_scripts_to_compile():
    assert len(SCRIPTS) > 10


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: str(p.relative_to(REPO)))
def test_the_script_compiles(path, tmp_path):
    py_compile.compile(str(path), cfile=str(tmp_path / "x.pyc"), doraise=True)
