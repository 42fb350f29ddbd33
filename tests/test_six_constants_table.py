"""The six-constant table of a variant (workflow/tools/six_constants_table.py),
end to end on records of linear anisotropic piles of known stiffness: the
piles it reads (only those whose probes have the stretch), all six constants
pinned in every core RVE, the anisotropy of the known C, the Voigt stiffness
given as 2 C twice the fitted in every modulus, and the centre contrast of a
centre softer by 30 % (with the fits of each RVE alone, m = 1: at m = 5 the
columns next to the centre's edge mix both materials)."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from synthetic_states import linear_probe_pile

from analysis import general_elastic as ge

REPO = Path(__file__).resolve().parents[1]
TOOL = [sys.executable, "-m", "workflow.tools", "six_constants_table"]
X = np.round(np.arange(-0.18, 0.1801, 0.015), 6)
Y = np.array([0.015, 0.03, 0.045, 0.06])


def _row(text, start):
    line = next(line for line in text.splitlines() if line.startswith(start))
    return [c.strip() for c in line.strip("|").split("|")]


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """A variant with a wedge pile of stiffness C (centre 30 % softer) probed with the stretch, a
    wedge pile without the stretch, and a study folder of two piles' fields."""
    rng = np.random.default_rng(7)
    q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    c = q @ np.diag([3.0e6, 1.2e6, 0.5e6]) @ q.T
    centre = np.abs(X) <= 0.03 + 1e-9
    c_field = np.broadcast_to(c, (len(Y), len(X), 3, 3)) * np.where(centre, 0.7, 1.0)[None, :, None, None]
    root = tmp_path_factory.mktemp("records")
    for folder in ("variant/wedge", "study/wedge"):
        (root / folder).mkdir(parents=True)
    probes, fields = linear_probe_pile(c_field, X, Y, rng)
    probes.to_netcdf(root / "variant/wedge/seed2.probes.nc")
    fields.to_netcdf(root / "variant/wedge/seed2.fields.nc")
    probes.drop_sel(probe="stretched").to_netcdf(root / "variant/wedge/seed3.probes.nc")
    fields.to_netcdf(root / "variant/wedge/seed3.fields.nc")
    for s in (1, 2):
        same_draws = np.random.default_rng(1)
        linear_probe_pile(c_field * (1 + 0.1 * s), X, Y, same_draws)[1].to_netcdf(
            root / f"study/wedge/seed{s}.fields.nc")
    return root, c


def test_the_table_of_a_known_linear_pile(records):
    root, c = records
    out = subprocess.run([*TOOL, "--variant", str(root / "variant"), "--study",
                          str(root / "study"), "--protocols", "wedge", "--params", '{"moduli": {"min_points": 3}}',
                          "--figure", str(root / "six.png"), "--points", "1"],
                         capture_output=True, text=True, check=True).stdout
    assert "wedge seed 2" in out and "wedge seed 3" not in out          # seed 3 has no stretch
    ident = _row(out, "| wedge seed 2 |")
    assert ident[2] == "100 %" and ident[3] == "100 %"
    assert _row(out, "| anisotropy E_max/E_min |")[1] == f"{float(ge.stiffness_axes(c)['anisotropy']):.3g} (1)"
    assert _row(out, "| angle stiffest axis to fabric axis, unsigned (deg) |")[1] == "10 (1)"
    for k in ("K", "E_av", "G_av"):
        assert _row(out, f"| wedge | {k} |")[-2] == "2.00 (1)"       # Voigt / general
    assert _row(out, "| general law G_av |")[1] == "-0.30 (1)"
    # the study's two piles differ by a factor of stiffness only, so their contrasts do not scatter
    assert _row(out, "| *seen at 80 %*")[1].startswith("±0.00 (SD 0.00, 1 pile)")
    assert (root / "six.png").stat().st_size > 10_000


def test_few_piles_name_students_t_from_the_tables():
    """Two-sided 5 % points of Student's t from printed tables: 12.706 (1 degree of freedom), 4.303 (2)."""
    from workflow.tools import six_constants_table as table
    assert table.few_piles({("wedge", 2): {}, ("layered", 2): {}}) == ""
    two = {(p, s): {} for p in ("wedge", "layered") for s in (2, 3)}
    assert "1 degree of freedom" in table.few_piles(two) and "beyond 12.7 standard errors" in table.few_piles(two)
    three = {**two, ("wedge", 4): {}, ("layered", 4): {}}
    assert "2 degrees of freedom" in table.few_piles(three) and "beyond 4.3 standard errors" in table.few_piles(three)
    assert table.few_piles({**three, **{(p, s): {} for p in ("wedge", "layered") for s in (5, 6)}}) == ""
