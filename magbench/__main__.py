"""``python -m magbench``: the same as the ``magbench`` command."""
from magbench.benchmarks.cli import run

raise SystemExit(run())
