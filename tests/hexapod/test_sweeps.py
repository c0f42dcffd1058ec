"""Design sweeps: serial and Dask give identical tables; invalid designs are reported."""

import pandas as pd
import pytest

from hexapod_pin.hexapod import sweeps


def test_design_grid_and_errors():
    grid = sweeps.design_grid(rail_radius=[0.3, 0.35], leg_length=[0.4, 0.45, 0.5])
    assert len(grid) == 6 and grid[0] == {"rail_radius": 0.3, "leg_length": 0.4}
    with pytest.raises(Exception, match="not a HexapodGeometry field"):
        sweeps.design_grid(rail_lenght=[1.0])


def test_serial_sweep_reports_invalid_designs_and_progress():
    seen = []
    designs = sweeps.design_grid(leg_length=[0.25, 0.45])  # 0.25 cannot assemble its home
    table = sweeps.design_sweep(designs, sweeps.SweepSettings(n_samples=2000, payload_samples=50),
                                use_dask=False, progress=lambda d, t: seen.append((d, t)))
    assert seen == [(1, 2), (2, 2)]
    assert list(table["valid"]) == [False, True]
    assert "cannot be assembled" in table["error"][0]
    assert pd.isna(table["reachable_volume"][0])
    assert table["reachable_volume"][1] > 0
    assert table["min_payload_kg"][1] > 0


def test_dask_and_serial_sweeps_are_identical():
    pytest.importorskip("dask.distributed")
    designs = sweeps.design_grid(rail_radius=[0.33, 0.37], platform_radius=[0.12])
    settings = sweeps.SweepSettings(n_samples=3000, payload_samples=100)
    serial = sweeps.design_sweep(designs, settings, use_dask=False)
    done = []
    parallel = sweeps.design_sweep(designs, settings, use_dask=True, n_workers=1,
                                   progress=lambda d, t: done.append(d))
    pd.testing.assert_frame_equal(serial, parallel)
    assert sorted(done) == [1, 2]
