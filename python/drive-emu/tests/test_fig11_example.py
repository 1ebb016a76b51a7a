"""python/examples/fig11.py runs and its check of the paper's Fig. 11 claim holds (the example
itself fails when a run leaves k_v/4 < f < k_v or f is not 0.6 k_v)."""
import subprocess
import sys
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "fig11.py"


def test_fig11_example_reproduces_the_claim(tmp_path):
    png = tmp_path / "fig11.png"
    done = subprocess.run([sys.executable, str(EXAMPLE), "--png", str(png)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{done.stdout}\n{done.stderr}"
    assert "Fig. 11 claim holds" in done.stdout, done.stdout
    assert "35 runs" in done.stdout, done.stdout
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
