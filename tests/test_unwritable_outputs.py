"""An output that cannot be written is refused before any work (issue 28): before, `film`
rendered and wrote the .mp4, then failed on an unwritable --html, leaving the film
without its page. The paths lie under a plain file, which no user (root included) can
make a folder of."""

import pytest

from analysis.__main__ import main as analysis_main


@pytest.fixture
def blocked(tmp_path):
    (tmp_path / "a_file").write_text("not a folder")
    return tmp_path / "a_file" / "sub"


def test_film_checks_both_outputs_before_rendering(tmp_path, blocked, capsys):
    film = tmp_path / "films" / "pour.mp4"
    assert analysis_main(["film", "--input", str(tmp_path / "never_read.nc"), "--out", str(film),
                          "--html", str(blocked / "pour.html")]) == 1
    err = capsys.readouterr().err
    assert f"--html {blocked / 'pour.html'}: cannot be written" in err and "nothing was made" in err
    assert "never_read.nc" not in err and not film.parent.exists()


def test_draw_checks_its_picture_before_reading_the_state(tmp_path, blocked, capsys):
    assert analysis_main(["draw", "--input", str(tmp_path / "never_read.nc"), "--out", str(blocked / "p.png")]) == 1
    err = capsys.readouterr().err
    assert f"--out {blocked / 'p.png'}: cannot be written" in err and "never_read.nc" not in err
