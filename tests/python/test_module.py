# The module behaves like a Python library: a version, thread control, docstrings and a type stub
# that names what the module has.
import ast
import pathlib
import re

import streetlight as sl

from conftest import ROOT


def test_version_is_the_changelogs_latest_release():
    assert re.fullmatch(r"\d+\.\d+\.\d+", sl.__version__)
    changelog = (ROOT / "CHANGELOG.md").read_text()
    released = re.findall(r"^## \[(\d+\.\d+\.\d+)\] - \d{4}-\d{2}-\d{2}", changelog, re.M)
    assert released and released[0] == sl.__version__


def test_set_num_threads_is_what_get_num_threads_reports():
    sl.set_num_threads(2)
    assert sl.get_num_threads() == 2
    sl.set_num_threads(1)
    assert sl.get_num_threads() == 1


def test_every_public_name_has_a_docstring_and_a_stub():
    stub = ROOT / "python" / "streetlight.pyi"
    tree = ast.parse(stub.read_text())
    stubbed = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    public = {n for n in dir(sl) if not n.startswith("_")}
    assert public == stubbed, f"module only: {public - stubbed}; stub only: {stubbed - public}"
    for name in ("Estimator", "insert", "train", "Tensor", "load_photo", "set_num_threads"):
        assert getattr(sl, name).__doc__, name
    assert "intrinsics" in sl.Estimator.estimate.__doc__
