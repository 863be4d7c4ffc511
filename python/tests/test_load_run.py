"""rephoto.load_run reads the tables by the C++ reader's rule (src/rephoto/run/run_table.h).

The expected values are written out by hand from the CSV text below (the rule: text columns as
str, counts as int with empty = 0, measurements as float with empty = NaN)."""
import math

import pytest

import rephoto

PER_IMAGE = (
    "name,status,photo,render,width,height,resized,completeness,valid_photo_windows,"
    "valid_both_windows,1-ncc,1-ncc_evaluated,psnr,psnr_evaluated\n"
    "a,ok,photos/a.png,renders/a.png,4,2,0,0.75,6,5,0.125,5,inf,8\n"
    "b,missing_render,photos/b.png,,,,,,,,,,,\n"
)


def write_compare_run(folder, per_image=PER_IMAGE):
    folder.mkdir()
    (folder / "per_image.csv").write_text(per_image)
    (folder / "summary.json").write_text('{"schema": "rephoto.compare/1"}')
    return folder


def test_tables_are_typed_by_the_cpp_rule(tmp_path):
    run = rephoto.load_run(write_compare_run(tmp_path / "run"))
    assert run.per_fold == []
    assert run.summary == {"schema": "rephoto.compare/1"}
    a, b = run.per_image
    assert list(a) == PER_IMAGE.splitlines()[0].split(",")
    assert a["name"] == "a" and a["render"] == "renders/a.png"
    assert a["width"] == 4 and isinstance(a["width"], int)
    assert a["completeness"] == 0.75 and a["1-ncc"] == 0.125 and a["1-ncc_evaluated"] == 5
    assert a["psnr"] == math.inf
    assert b["status"] == "missing_render" and b["render"] == ""
    assert b["width"] == 0 and b["1-ncc_evaluated"] == 0
    assert math.isnan(b["completeness"]) and math.isnan(b["1-ncc"])


def test_junk_in_a_table_is_an_error_naming_line_and_column(tmp_path):
    run = write_compare_run(tmp_path / "run", PER_IMAGE.replace("0.125", "good"))
    with pytest.raises(rephoto.Error, match=r'per_image.csv: line 2: column "1-ncc": "good" is not a number'):
        rephoto.load_run(run)
    with pytest.raises(rephoto.Error, match="not a directory"):
        rephoto.load_run(tmp_path / "nope")
