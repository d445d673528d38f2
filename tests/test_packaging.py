"""Packaging: the wheel installs only names of its own (signlane, signlane_train, signlane_export,
signlane_data), every package folder is in it, nothing imports the folders' bare names, the
runtime never pulls in torch, and the licence is there."""
import ast
import importlib.util
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FOLDERS = {"signlane": "signlane", "train": "signlane_train", "export": "signlane_export", "data_gen": "signlane_data"}


def setuptools_config() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def test_every_package_folder_installs_under_a_signlane_name():
    cfg = setuptools_config()
    packages, package_dir = set(cfg["packages"]), cfg.get("package-dir", {})
    assert all(p.split(".")[0].startswith("signlane") for p in packages), packages
    assert package_dir == {v: k for k, v in FOLDERS.items() if k != v}
    found = set()
    for folder, name in FOLDERS.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / folder).parts
            found.add(".".join((name, *rel)))
    assert found == packages, f"missing from pyproject: {found - packages}; listed but absent: {packages - found}"


def test_the_installed_names_point_at_the_repository_folders():
    for folder, name in FOLDERS.items():
        spec = importlib.util.find_spec(name)
        assert spec is not None and Path(spec.origin).parent == ROOT / folder, (name, spec)


def test_no_module_imports_the_bare_folder_names():
    bare = {k for k, v in FOLDERS.items() if k != v}
    offenders = []
    for path in ROOT.rglob("*.py"):
        if ".venv" in path.parts:
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else []
            offenders += [f"{path.relative_to(ROOT)}:{node.lineno} {n}" for n in names if n.split(".")[0] in bare]
    assert not offenders, offenders


def test_the_runtime_never_imports_torch():
    code = ("import sys, signlane, signlane.cli, signlane.infer, signlane.pipeline, signlane.sim.server, "
            "signlane.sim.session, signlane.sim.driver, signlane.draw, signlane.demo\n"
            "from signlane.cli import main\n"
            "try:\n    main(['drive', '--help'])\nexcept SystemExit:\n    pass\n"
            "print('torch' in sys.modules, 'lightning' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True).stdout
    assert out.strip().splitlines()[-1] == "False False"


def test_licence_and_no_unused_pins():
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License") and "Copyright (c) the signlane authors" in text
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    train = project["optional-dependencies"]["train"]
    assert not any(d.startswith("torchvision") for d in train) and "torch==2.14.1" in train
    assert any(d.startswith("av") for d in project["dependencies"])
