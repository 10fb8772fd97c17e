import sys
import textwrap

import pytest

from magbench.calibrators import available, register, registry
from magbench.calibrators.methods.lsq import LeastSquares


def test_duplicate_name_refused():
    class Impostor(LeastSquares):
        name = "lsq"

    with pytest.raises(ValueError, match="already registered"):
        register(Impostor)
    assert available()["lsq"] is LeastSquares


def test_entry_point_plugin_is_discovered(tmp_path, monkeypatch):
    """An installed package adds a calibrator through the 'magbench.calibrators' entry-point group."""
    (tmp_path / "magbench_demo_plugin.py").write_text(textwrap.dedent("""
        from magbench.calibrators.methods.lsq import LeastSquares

        class Plugin(LeastSquares):
            name = "plugin-lsq"
            summary = "lsq under another name, from an installed plug-in"
    """))
    dist = tmp_path / "magbench_demo_plugin-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: magbench-demo-plugin\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(
        "[magbench.calibrators]\nplugin-lsq = magbench_demo_plugin:Plugin\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_plugins_loaded", False)
    try:
        cals = available()
        assert "plugin-lsq" in cals
        from magbench.calibrators import check_calibrator

        assert check_calibrator(cals["plugin-lsq"], models=["angles"])
    finally:
        registry.unregister("plugin-lsq")
        sys.modules.pop("magbench_demo_plugin", None)


def _install_plugin(tmp_path, monkeypatch, module_text: str, entry_points: str):
    name = "magbench_bad_plugin"
    (tmp_path / f"{name}.py").write_text(textwrap.dedent(module_text))
    dist = tmp_path / f"{name}-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: magbench-bad-plugin\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[magbench.calibrators]\n" + textwrap.dedent(entry_points))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_plugins_loaded", False)
    monkeypatch.setattr(registry, "_plugin_errors", {})
    monkeypatch.delitem(sys.modules, name, raising=False)


def test_broken_plugins_are_listed_with_the_reason_and_never_harm_the_registry(tmp_path, monkeypatch, capsys):
    from magbench.benchmarks.cli import main
    from magbench.calibrators import make
    from magbench.errors import InputError

    _install_plugin(tmp_path, monkeypatch, """
        from magbench.calibrators.methods.lsq import LeastSquares

        def not_a_class():
            return 1

        class Shadow(LeastSquares):
            name = "lsq"
    """, """
        broken-import = magbench_no_such_module:Thing
        a-function = magbench_bad_plugin:not_a_class
        lsq = magbench_bad_plugin:Shadow
    """)
    errors = registry.plugin_errors()
    assert "failed to import" in errors["broken-import"] and "ModuleNotFoundError" in errors["broken-import"]
    assert "not a Calibrator subclass" in errors["a-function"]
    assert "already registered" in errors["lsq"]
    assert available()["lsq"] is LeastSquares  # the built-in is untouched
    assert make("lsq").name == "lsq"
    with pytest.raises(InputError, match="unavailable: entry point broken-import"):
        make("broken-import")
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "plug-ins that did not load" in out and "broken-import" in out and "a-function" in out
    assert main(["list", "--json"]) == 0
    import json

    listed = {p["name"] for p in json.loads(capsys.readouterr().out)["unavailable_plugins"]}
    assert listed == {"broken-import", "a-function", "lsq"}
    assert main(["calibrate", "nothing.csv", "--method", "a-function"]) == 2
    assert "not a Calibrator subclass" in capsys.readouterr().err


def test_register_refuses_a_function_and_a_taken_name_without_side_effects():
    before = dict(available())
    with pytest.raises(ValueError, match="not a Calibrator subclass"):
        register(lambda: None)
    with pytest.raises(ValueError, match="already registered"):
        register(type("Twin", (LeastSquares,), {"name": "lsq"}))
    assert available() == before
