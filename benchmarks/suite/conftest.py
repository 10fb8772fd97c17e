import os

import numpy as np
import pytest

from magbench.simulate import simulate


@pytest.fixture(scope="session", autouse=True)
def _bytecode_written():
    """Whole-process benchmarks time a command as an installed package runs it, its bytecode compiled (pip compiles
    it on install; the untimed first round writes it in a source checkout).  ``PYTHONDONTWRITEBYTECODE``, which some
    environments set, would instead have every process recompile each module whose source changed since its cached
    bytecode: that compile, not the command, would be timed (0.09 s more for ``magbench --help`` after an edit)."""
    saved = os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    yield
    if saved is not None:
        os.environ["PYTHONDONTWRITEBYTECODE"] = saved


@pytest.fixture(scope="session")
def lu2014():
    return simulate("lu2014", 0)


@pytest.fixture(scope="session")
def sphere9():
    return simulate("sphere9", 0)


def _write_csv(path, columns: np.ndarray, header: str, fmt: str = "%.3f", block: int = 200_000) -> None:
    """``np.savetxt(path, columns, delimiter=",", header=header, comments="", fmt=fmt)``, byte for byte, in
    2.3x less time on 2e6 rows (one %-format of a block of rows, in C, where savetxt formats row by row)."""
    row = ",".join([fmt] * columns.shape[1]) + "\n"
    with open(path, "w", encoding="ascii", newline="") as f:
        f.write(header + "\n")
        for start in range(0, len(columns), block):
            part = columns[start:start + block]
            f.write((row * len(part)) % tuple(part.ravel().tolist()))


@pytest.fixture(scope="session")
def write_csv():
    """``_write_csv``: large generated records written as ``np.savetxt`` would, faster."""
    return _write_csv
