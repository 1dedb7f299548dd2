"""The type stub of the compiled module is current: regenerating it from the installed module
gives the committed text (tools/gen_native_stub.py), and the package is marked typed."""

import importlib.util
import pathlib

import sdtoolkit

REPO = pathlib.Path(__file__).resolve().parents[2]


def test_native_stub_is_current_and_the_package_is_typed():
    spec = importlib.util.spec_from_file_location("gen_native_stub", REPO / "tools" / "gen_native_stub.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    committed = (REPO / "sd-python" / "python" / "sdtoolkit" / "_native.pyi").read_text()
    assert gen.render() == committed, "run `python tools/gen_native_stub.py`"
    pkg = pathlib.Path(sdtoolkit.__file__).parent
    assert (pkg / "py.typed").exists() and (pkg / "_native.pyi").exists()
