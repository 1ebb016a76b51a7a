"""One name per parameter (issue 29): a sweep grid takes the parameter registry's names (the
names of `--set`, scenario files, `drive-emu sweep --kv-per-s/--backlash-mm`); the keys that
moved (`kv`, `backlash`) still work for one release with a DeprecationWarning; a typo gets the
name that was meant. Each case is out of range or misspelt, so it is refused before any run:
nothing is simulated."""
import warnings

import pytest

import drive_emu


def _refused(case):
    with pytest.raises(ValueError) as e:
        drive_emu.sweep([case], workers=1, progress=False)
    return str(e.value)


def test_registry_names_are_taken_without_a_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = _refused({"preset": "cnc1", "kv_per_s": 2000})
        assert "kv_per_s" in m and "2000" in m, m
        m = _refused({"preset": "cnc3", "backlash_deg": 100})
        assert "backlash_deg" in m and "must be <= 5.7" in m, m


def test_moved_grid_keys_warn_and_reach_the_new_name():
    with pytest.warns(DeprecationWarning, match="`kv` is now `kv_per_s`") as w:
        m = _refused({"preset": "cnc1", "kv": 2000})
    # the value went to kv_per_s: its range refused it under that name
    assert "kv_per_s=2000" in m and "kv_per_s" in m, m
    # attributed to this file (the caller), where Python's default filters show it
    assert all(r.filename == __file__ for r in w), [r.filename for r in w]
    with pytest.warns(DeprecationWarning, match="`backlash` is now `backlash_mm`"):
        m = _refused({"preset": "cnc1", "backlash": 100})
    assert "backlash_mm" in m, m
    with pytest.warns(DeprecationWarning):
        m = _refused({"preset": "cnc1", "kv": 30, "kv_per_s": 30})
    assert "both given" in m, m


def test_a_typo_gets_the_registry_name():
    m = _refused({"preset": "cnc1", "kv_pers": 30})
    assert "did you mean `kv_per_s`" in m, m
    m = _refused({"preset": "cnc1", "backlsh_mm": 0.02})
    assert "did you mean `backlash_mm`" in m, m
