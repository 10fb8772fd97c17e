"""Seed 000's Table 2 (real FGM-2000 turntable data), every row tested (as ahrs tests every row of the
WMM reference table): the shipped file (magbench.simulate data/lu2014_table2.csv) against the paper's
printed rows, copied below from the paper's text, and each row's printed error against its own field
values and the reference the file states."""
from importlib import resources

import numpy as np
import pytest

from magbench.simulate.dataset import read_csv

# Table 2 as printed (seeds/000, "表2 校正前后测量结果及误差对比 单位:nT"):
# point, total field before, error before, total field after, error after
PAPER_TABLE_2 = """
            1  52069.25    -90.51  51958.08     20.66
            2  52069.24     -90.5  51986.59     -7.84
            3  52026.27    -47.53  52002.47    -23.72
            4  51960.31     18.43  52015.74    -36.99
            5  51884.26     94.48  52031.32    -52.58
            6  51812.21    166.53  52043.03    -64.29
            7  51741.47    237.26  52040.98    -62.24
            8   51685.9    292.84  52020.62    -41.88
            9  51667.24    311.49  51999.52    -20.78
           10  51682.81    295.93  51970.85      7.89
           11  51851.49    127.25  51928.97     49.77
           12  51979.74     -0.99  51914.76     63.98
           13  52116.23   -137.48  51899.83      78.9
           14  52258.52   -279.77  51892.94      85.8
           15  52384.56   -405.82  51894.74     83.99
           16  52557.17   -578.43  51933.84     44.89
           17  52584.56   -605.81  51967.52     11.22
           18  52555.33   -576.58  51995.78    -17.03
           19  52483.51   -504.76  52024.22    -45.48
           20  52370.67   -391.93  52048.37    -69.64
           21  52228.58   -249.84  52061.87    -83.13
           22  52072.99    -94.24   52070.7    -91.96
           23  51925.43     53.31  52070.28    -91.53
           24  51782.46    196.28  52055.33    -76.59
           25  51669.76    308.98  52031.81    -53.06
           26  51599.86    378.88  52006.46    -27.72
           27  51566.32    412.42  51973.77      4.97
           28  51577.15    401.59  51945.07     33.66
           29  51626.31    352.43  51920.55     58.19
           30  51701.78    276.95  51901.42     77.32
           31  51790.44     188.3  51890.39     88.34
           32   51887.3     91.44  51897.00     81.74
           33   51974.5      4.24  51911.71     67.03
           34  52037.51    -58.77  51933.54     45.19
           35  52074.83    -96.08  51963.52     15.22
"""
PAPER_ROWS = [tuple(float(v) for v in line.split()) for line in PAPER_TABLE_2.strip().splitlines()]
F_REF_NT = 51978.74  # the reference that makes the printed errors consistent (the file's '# field_nT:')
PRINT_RESOLUTION_NT = 0.01


@pytest.fixture(scope="module")
def table2():
    path = resources.files("magbench.simulate").joinpath("data/lu2014_table2.csv")
    return read_csv(str(path), require_vector=False)


def test_the_file_has_every_row_of_the_paper(table2):
    assert len(PAPER_ROWS) == 35
    assert len(table2) == len(PAPER_ROWS)


@pytest.mark.parametrize("row", PAPER_ROWS, ids=[f"point{int(r[0])}" for r in PAPER_ROWS])
def test_row(table2, row):
    point, f_before, err_before, f_after, err_after = row
    i = int(point) - 1
    assert table2.heading_deg[i] == pytest.approx(10.0 * i)  # one reading every 10 degrees (section 3)
    assert table2.f_meas_nT[i] == pytest.approx(f_before, abs=1e-9)
    assert table2.extra["f_meas_after"][i] == pytest.approx(f_after, abs=1e-9)
    assert table2.f_ref_nT[i] == pytest.approx(F_REF_NT, abs=1e-9)
    # the printed errors are reference minus measurement, to the table's 0.01 nT
    assert F_REF_NT - f_before == pytest.approx(err_before, abs=PRINT_RESOLUTION_NT + 1e-9)
    assert F_REF_NT - f_after == pytest.approx(err_after, abs=PRINT_RESOLUTION_NT + 1e-9)


def test_the_rms_the_rows_give():
    """The rows give 294.87 -> 57.81 nT (80.4 %); the paper's text says 411.82 -> 49.38 nT, which no
    reading of the rows reproduces (results/lu2014_tables.md states both)."""
    rows = np.array(PAPER_ROWS)
    assert np.sqrt(np.mean(rows[:, 2] ** 2)) == pytest.approx(294.87, abs=0.01)
    assert np.sqrt(np.mean(rows[:, 4] ** 2)) == pytest.approx(57.81, abs=0.01)
