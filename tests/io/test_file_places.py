"""Messages that name what is wrong with an input place (issue 43): a folder or a link loop
where a file is expected says so (was 'file not found'), a COLMAP model folder without
images.txt names the missing file (was 'not a COLMAP model')."""

import shutil
from pathlib import Path

import pytest

from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.bal import read_bal
from baarda.io.bundler import read_bundler
from baarda.io.nvm import read_nvm
from baarda.io.residual_listings import detect

MAUPERTUIS = Path(__file__).parents[1] / "data" / "colmap_maupertuis" / "sparse"


def _places(tmp_path: Path) -> dict[str, Path]:
    folder = tmp_path / "a_folder.txt"
    folder.mkdir()
    loop = tmp_path / "loop.txt"
    loop.symlink_to("loop.txt")
    return {"is a folder, not a regular file": folder,
            "is a symbolic link loop, not a file": loop}


@pytest.mark.parametrize("reader", [read_bal, read_nvm, read_bundler, detect])
def test_a_folder_or_a_link_loop_where_a_file_is_expected_says_so(tmp_path, reader):
    for said, path in _places(tmp_path).items():
        if reader is read_bundler and path.is_dir():
            continue  # Bundler's folder holds bundle.out: read_bundler takes it
        with pytest.raises(ProjectError) as e:
            reader(path)
        assert str(e.value) == f"{path}: {said}"


def test_the_command_line_says_so_too(tmp_path, capsys):
    for said, path in _places(tmp_path).items():
        assert main(["residuals", str(path)]) == 2
        assert f"{path}: {said}" in capsys.readouterr().err
    loop = tmp_path / "loop.txt"
    assert main(["adjust", str(loop), "--format", "bal", "-o", str(tmp_path / "o")]) == 2
    assert "symbolic link loop" in capsys.readouterr().err


@pytest.mark.parametrize("missing", ["images", "cameras", "points3D"])
def test_a_colmap_folder_without_a_model_file_names_it(tmp_path, capsys, missing):
    model = tmp_path / "sparse"
    shutil.copytree(MAUPERTUIS, model)
    (model / f"{missing}.txt").unlink()
    for fmt in ([], ["--format", "colmap"]):
        assert main(["adjust", str(tmp_path), *fmt, "-o", str(tmp_path / "o"), "-q"]) == 2
        err = capsys.readouterr().err
        assert f"{model / missing}.txt: not found: a COLMAP model folder holds cameras.txt, " \
               "images.txt, points3D.txt; this one has " in err, err
    assert not (tmp_path / "o").exists()
