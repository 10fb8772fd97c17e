"""``python -m magbench``: the same as the ``magbench`` command."""
from magbench.benchmarks.cli import main

raise SystemExit(main())
