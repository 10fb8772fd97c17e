"""magbench's harness: runs, metrics, tables and the ``magbench`` command."""
