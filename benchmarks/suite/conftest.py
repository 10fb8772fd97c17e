import pytest

from magbench.simulate import simulate


@pytest.fixture(scope="session")
def lu2014():
    return simulate("lu2014", 0)


@pytest.fixture(scope="session")
def sphere9():
    return simulate("sphere9", 0)
