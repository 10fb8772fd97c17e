"""magbench: simulate tri-axial fluxgate magnetometers in the geomagnetic field and benchmark the
algorithms that calibrate them.

One import namespace (CONTRACT section 4): ``magbench.simulate`` (the forward model),
``magbench.calibrators`` (one interface, one counted objective, the registry and the conformance
battery) and ``magbench.benchmarks`` (the harness, the diagnosis and the ``magbench`` command).
The repository keeps these as its top-level folders ``simulate/``, ``calibrators/`` and
``benchmarks/``; ``pyproject.toml`` maps them under this package.
"""
__version__ = "0.2.0"

__all__ = ["__version__"]
