"""Fuzzing the native project (examples/demo: project.toml and four CSV files)."""

from fuzz.fuzzing import ADJUST_DEADLINE_MS, any_mutations, format_tests, read_test

from baarda.pipeline import read_models

test_read_project, test_adjust_project = format_tests("project", "project_base")

# read_models of a photo project forms stereo models by relative orientation
test_read_models_of_a_photo_project = read_test(
    "project read_models", "project_base", read_models, draw=any_mutations, computes=True,
    deadline_ms=ADJUST_DEADLINE_MS)


# ---------------------------------------------------------------- issue 28
CSV = ["cameras.csv", "photos.csv", "image_points.csv", "ground_points.csv"]


def _outcome(files: dict[str, bytes], work):
    """What reading `files` gives: the block's ids and arrays, or the error's message (with
    the folder left out)."""
    import tempfile
    from pathlib import Path

    import numpy as np
    from fuzz.fuzzing import check_read, write_files

    from baarda.pipeline import read

    with tempfile.TemporaryDirectory(dir=work) as d:
        root = Path(d) / "in"
        write_files(root, files)
        r = check_read(read, root)
        if isinstance(r, Exception):
            return type(r).__name__, str(r).replace(str(root), "IN")
        return (r.photos.ids, r.points.ids, list(r.points.role), r.cameras.ids,
                np.asarray(r.image.xy_mm).tobytes(), np.asarray(r.points.xyz).tobytes())


def _two_boms_test():
    """Two byte-order marks before a CSV file of a (mildly mutated) project change nothing:
    the same block, or the same error."""
    from fuzz.fuzzing import TWO_BOMS, _fuzz_test, apply, mutations
    from hypothesis import strategies as st

    def body(base, work, data):
        muts = data.draw(mutations(base, files=CSV, mild=True))
        name = data.draw(st.sampled_from(CSV))
        plain = apply(base, muts)
        joined = dict(plain)
        if name in joined:
            joined[name] = TWO_BOMS + joined[name]
        assert _outcome(joined, work) == _outcome(plain, work)

    return _fuzz_test("project two boms", "project_base", 3000, body)


def _nul_test():
    """A NUL byte anywhere in a field of a valid project's CSV file: the error names that
    file and line (it surfaced as an unknown id of another file)."""
    from pathlib import Path

    from fuzz.fuzzing import _fuzz_test, read_case
    from hypothesis import strategies as st

    from baarda.errors import ProjectError

    def body(base, work, data):
        name = data.draw(st.sampled_from(CSV))
        lines = base.files[name].split(b"\n")
        i = data.draw(st.integers(0, len(lines) - 1).filter(lambda k: lines[k].strip()))
        j = data.draw(st.integers(0, len(lines[i])))
        files = dict(base.files, **{name: b"\n".join(
            lines[:i] + [lines[i][:j] + b"\x00" + lines[i][j:]] + lines[i + 1:])})
        from fuzz.fuzzing import Base

        from baarda.pipeline import read

        r = read_case(Base(files, base.kinds), [], work, read)
        assert isinstance(r, ProjectError), r
        assert Path(r.path).name == name and r.line == i + 1 and "NUL" in r.detail, r

    return _fuzz_test("project nul", "project_base", 3000, body)


test_two_byte_order_marks_change_nothing = _two_boms_test()
test_a_nul_byte_is_named_where_it_is = _nul_test()
