"""radbench's pytest plugin (entry point ``pytest11``): a ``mock_lab`` fixture, so a test of
your own pyvisa code runs against radbench's simulated bench with one argument::

    def test_my_scope_script(mock_lab):
        rm = pyvisa.ResourceManager("@py")
        scope = rm.open_resource(mock_lab.resources["scope"])
        assert "LABMASTER" in scope.query("*IDN?")

Each test gets a fresh bench (a :class:`radbench.MockLab`), stopped after it. The marker
``@pytest.mark.mock_lab(scene=..., scope_remote=...)`` passes its arguments to ``MockLab``.

``radbench_bench`` is a :class:`radbench.Bench` (RF permitted: the bench is simulated) on that
fresh ``mock_lab``, closed after the test::

    def test_my_analysis(radbench_bench, mock_lab):
        mock_lab.move(0, 2.0)
        assert abs(radbench_bench.capture().ranges_m[0] - 2.0) < 0.01
"""

from __future__ import annotations

from typing import Iterator

import pytest

from ._bench import Bench
from ._lab import MockLab


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "mock_lab(scene=None, scope_remote='vxi11'): how the mock_lab fixture starts radbench's "
        "simulated bench",
    )


@pytest.fixture
def mock_lab(request: pytest.FixtureRequest) -> Iterator[MockLab]:
    """radbench's simulated bench on 127.0.0.1, running for this test (``radbench.MockLab``)."""
    marker = request.node.get_closest_marker("mock_lab")
    kwargs = dict(marker.kwargs) if marker else {}
    args = marker.args if marker else ()
    with MockLab(*args, **kwargs) as lab:
        yield lab


@pytest.fixture
def radbench_bench(mock_lab: MockLab) -> Iterator[Bench]:
    """A warm :class:`radbench.Bench` on this test's ``mock_lab`` (RF permitted), closed after
    it."""
    with Bench(mock_lab, allow_rf=True) as bench:
        yield bench
