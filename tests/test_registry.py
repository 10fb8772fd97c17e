import sys
import textwrap

import pytest

from magbench.calibrators import available, register, registry
from magbench.calibrators.lsq import LeastSquares


def test_duplicate_name_refused():
    class Impostor(LeastSquares):
        name = "lsq"

    with pytest.raises(ValueError, match="already registered"):
        register(Impostor)
    assert available()["lsq"] is LeastSquares


def test_entry_point_plugin_is_discovered(tmp_path, monkeypatch):
    """An installed package adds a calibrator through the 'magbench.calibrators' entry-point group."""
    (tmp_path / "magbench_demo_plugin.py").write_text(textwrap.dedent("""
        from magbench.calibrators.lsq import LeastSquares

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
