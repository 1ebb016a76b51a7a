"""drive_emu.sweep: a 1000-run sweep on two local threads and on a Dask LocalCluster with two
workers gives equal results; rows equal `drive-emu sweep`'s for the same grid; Parquet holds
the table; the grid forms."""
import itertools
import json
from collections.abc import Sequence

import numpy as np
import pandas as pd
import pytest

import drive_emu

# 1000 short runs (2 simulated s each: about 1 ms of work) over k_v, gap, speed and friction.
GRID = {
    "preset": "cnc1",
    "kv_per_s": np.linspace(15.0, 60.0, 10),
    "backlash_mm": [0.02, 0.03, 0.05, 0.07, 0.1],
    "velocity": [5.0, 10.0, 20.0, -20.0],
    "load_coulomb_friction_n": [3.0, 30.0, 300.0, 600.0, 900.0],
    "duration": 2.0,
}


@pytest.fixture(scope="module")
def local_1000():
    return drive_emu.sweep(GRID, workers=2, progress=False)


def test_local_sweep_has_a_row_per_case_in_grid_order(local_1000):
    t = local_1000
    assert len(t) == 1000
    assert list(t.columns[:5]) == ["preset", "kv_per_s", "backlash_mm", "load_coulomb_friction_n",
                                   "duration_s"]
    # first key slowest, last fastest
    assert t.kv_per_s.iloc[0] == t.kv_per_s.iloc[99] == 15.0 and t.kv_per_s.iloc[100] == 20.0
    assert list(t.load_coulomb_friction_n.iloc[:5]) == [3.0, 30.0, 300.0, 600.0, 900.0]
    assert (t.backlash == t.backlash_mm).all(), "the measured case is the one asked for"
    assert (t.duration_s == 2.0).all()
    # physics, not a snapshot: at low drag every run oscillates in the paper's band, and a
    # run whose drag number is far above the cycle's limit does not oscillate
    low_drag = t[t.drag_number < 1.0]
    assert len(low_drag) > 100 and low_drag.in_band.all()
    assert not t[t.drag_number > 5.0].limit_cycle.any()


def test_dask_local_cluster_gives_the_same_table(local_1000):
    from distributed import Client, LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        assert len(client.scheduler_info()["workers"]) == 2
        on_dask = drive_emu.sweep(GRID, client=client, progress=False)
    pd.testing.assert_frame_equal(on_dask, local_1000, check_exact=True)


def test_one_thread_gives_the_same_table(local_1000):
    cases = drive_emu._grid_cases(GRID)[::37]
    one = drive_emu.sweep(cases, workers=1, progress=False)
    pd.testing.assert_frame_equal(one, local_1000.iloc[::37].reset_index(drop=True),
                                  check_exact=True)


def test_parquet_holds_the_table(local_1000, tmp_path):
    path = tmp_path / "sweep.parquet"
    t = drive_emu.sweep(drive_emu._grid_cases(GRID)[:50], workers=2, progress=False, out=path)
    back = pd.read_parquet(path)
    pd.testing.assert_frame_equal(back, t, check_exact=True)
    pd.testing.assert_frame_equal(t, local_1000.iloc[:50], check_exact=True)


def test_rows_equal_the_cli_sweep(cli, tmp_path):
    cli("sweep", "--preset", "cnc1,cnc3", "--kv-per-s", "0.5x..2x:3", "--backlash-mm",
        "0.5x,1x", "--backlash-deg", "0.5x,1x", "--duration", "3", "--threads", "2", "--out",
        tmp_path)
    want = json.loads((tmp_path / "sweep.json").read_text())
    cases = [{"preset": p, "kv_per_s": kv, key: b, "duration": 3.0}
             for p, own_kv, key, own_b in [("cnc1", 30.0, "backlash_mm", 0.03),
                                          ("cnc3", 16.7, "backlash_deg", 0.02)]
             for kv in np.linspace(0.5, 2.0, 3) * own_kv for b in (0.5 * own_b, own_b)]
    got = drive_emu.sweep(cases, progress=False)
    assert len(got) == len(want)
    for i, w in enumerate(want):
        row = got.iloc[i]
        for key, value in w.items():
            g = row[key]
            if value is None:
                assert pd.isna(g), (i, key)
            else:
                assert g == value, f"row {i} {key}: python {g!r} != cli {value!r}"


def test_grid_forms_give_the_same_cases():
    grid = {"preset": ["cnc1", "cnc3"], "kv_per_s": [20, 40], "noise_seed": 3}
    as_dict = drive_emu._grid_cases(grid)
    assert as_dict == [
        {"preset": "cnc1", "kv_per_s": 20, "noise_seed": 3},
        {"preset": "cnc1", "kv_per_s": 40, "noise_seed": 3},
        {"preset": "cnc3", "kv_per_s": 20, "noise_seed": 3},
        {"preset": "cnc3", "kv_per_s": 40, "noise_seed": 3},
    ]
    assert drive_emu._grid_cases(pd.DataFrame(as_dict)) == as_dict
    assert drive_emu._grid_cases(as_dict) == as_dict


def test_seed_and_noise_reach_the_run():
    t = drive_emu.sweep({"motor_encoder_noise_counts": [0.0, 50.0], "noise_seed": [1, 2],
                         "duration": 3.0}, progress=False)
    quiet = t[t.motor_encoder_noise_counts == 0.0]
    noisy = t[t.motor_encoder_noise_counts == 50.0]
    # without noise the seed changes nothing; with noise each seed gives another run
    assert quiet.iloc[0].fundamental_hz == quiet.iloc[1].fundamental_hz
    assert quiet.iloc[0].motor_velocity_amplitude_rpm == quiet.iloc[1].motor_velocity_amplitude_rpm
    assert noisy.iloc[0].motor_velocity_amplitude_rpm != noisy.iloc[1].motor_velocity_amplitude_rpm


def test_progress_bar_counts_every_run(capsys):
    drive_emu.sweep({"kv_per_s": [20, 30, 40], "duration": 2.0}, progress=True)
    err = capsys.readouterr().err
    assert "3/3" in err, err


def test_a_grid_beyond_the_cap_is_refused_before_it_is_built(monkeypatch):
    # issue 32: a grid over range(10**9) built 10**9 cases first (MemoryError); it is counted
    # and refused with the cap, as is a product of smaller axes and an endless generator of a
    # key's values (kept: each is needed once per combination of the keys before it)
    assert drive_emu.MAX_SWEEP_CASES == 1_000_000
    cap = 1000  # the same rule at a size a test can build
    monkeypatch.setattr(drive_emu, "MAX_SWEEP_CASES", cap)
    for grid, said in [
        ({"kv_per_s": range(10**9)}, "1,000,000,000 cases"),
        ({"kv_per_s": range(20), "backlash_mm": range(100)}, "2,000 cases"),
        ({"kv_per_s": (20.0 + i for i in itertools.count())}, "more than"),
    ]:
        with pytest.raises(ValueError, match="split the grid") as e:
            drive_emu.sweep(grid, progress=False)
        assert said in str(e.value), str(e.value)
        assert f"{cap:,}" in str(e.value)
    # at the cap itself the grid is built (not run here)
    assert len(drive_emu._grid_cases({"kv_per_s": range(cap)})) == cap
    assert len(drive_emu._grid_cases(({"kv_per_s": k} for k in range(cap)))) == cap


def test_range_of_a_billion_is_refused_at_once_without_building_a_case():
    # issue 32, at the real cap: counted by len(), refused before any case is made
    with pytest.raises(ValueError, match="1,000,000,000 cases") as e:
        drive_emu.sweep({"kv_per_s": range(10**9)}, progress=False)
    assert f"{drive_emu.MAX_SWEEP_CASES:,}" in str(e.value)

    class Billion(Sequence):
        """A list of 10**9 case dicts that says when a case is made."""
        made = 0

        def __len__(self):
            return 10**9

        def __getitem__(self, i):
            Billion.made += 1
            return {"kv_per_s": 20.0}

    with pytest.raises(ValueError, match="1,000,000,000 cases"):
        drive_emu.sweep(Billion(), progress=False)
    assert Billion.made == 0


def endless(made):
    """Cases without end (2 simulated s each), counting in `made[0]` how many were taken."""
    for i in itertools.count():
        made[0] += 1
        yield {"kv_per_s": 20.0 + (i % 40), "duration": 2.0}


def test_a_generator_grid_is_taken_a_chunk_at_a_time_as_the_runs_go(monkeypatch):
    # issue 32: the cases are made from the grid's iterator as they run, never the grid
    # first: of an endless generator, the first chunk's rows come back with only that chunk
    # taken from it
    monkeypatch.setattr(drive_emu, "_SWEEP_CHUNK", 20)
    made = [0]
    chunks = drive_emu._sweep_chunks(*drive_emu._grid_iter(endless(made)), workers=1)
    cases, rows = next(chunks)
    assert made[0] == 20 and len(cases) == len(rows) == 20
    assert [r["kv_per_s"] for r in rows] == [20.0 + i for i in range(20)]
    cases, rows = next(chunks)
    assert made[0] == 40 and [r["kv_per_s"] for r in rows] == [40.0 + i for i in range(20)]
    chunks.close()


def test_an_endless_generator_grid_stops_at_the_cap_with_a_clear_error(monkeypatch):
    cap = 5
    monkeypatch.setattr(drive_emu, "MAX_SWEEP_CASES", cap)
    made = [0]
    with pytest.raises(ValueError, match="split the grid") as e:
        drive_emu.sweep(endless(made), progress=False)
    assert "more than 5" in str(e.value)
    # one case past the cap was taken to know, and no more
    assert made[0] == cap + 1
    # a generator of the cap's size runs to its end
    made = [0]
    t = drive_emu.sweep(itertools.islice(endless(made), cap), workers=1, progress=False)
    assert len(t) == cap and made[0] == cap
