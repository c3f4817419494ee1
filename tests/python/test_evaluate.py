# streetlight.evaluate: streetlight-eval from Python (tools/common/evaluation.h). On a tiny
# generated street dataset it returns the tool's results.json (timing fields aside), and bad input
# raises the module's exceptions with the library's message.
import json
import subprocess

import pytest

import streetlight as sl

# The generator's defaults shrunk to thumbnail size (tests/support/street_fixture.h tiny_generator_tree).
TINY_STREETS = {
    "samples": 4, "seed": 7,
    "render": {"spp": 2, "max_depth": 2, "environment_width": 64},
    "panorama": {"width": 32, "height": 16},
    "views": {"width": 48, "height": 24},
    "sky": {"width": 32, "height": 8},
    "insertion": {"min_visible_pixels": 4, "coverage_samples": 2},
    "splits": {"train": 0.5, "val": 0.0},
}


@pytest.fixture(scope="module")
def streets(tmp_path_factory, tool):
    folder = tmp_path_factory.mktemp("evaluate")
    config = folder / "streets.json"
    config.write_text(json.dumps(TINY_STREETS))
    out = folder / "streets"
    run = subprocess.run([tool("streetlight-datagen"), "--config", str(config), "--out", str(out)],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    return out


def without_timing(value):
    """results.json without its wall-clock fields: inference_ms, and each budget's ms."""
    if isinstance(value, dict):
        return {k: without_timing(v) for k, v in value.items() if k not in ("inference_ms", "ms")}
    if isinstance(value, list):
        return [without_timing(v) for v in value]
    return value


def test_evaluate_returns_the_tools_results_json(streets, tool, released, tmp_path):
    run = subprocess.run([tool("streetlight-eval"), "--data", str(streets), "--view-rows", "8",
                          "--out", str(tmp_path / "tool")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    expected = json.loads((tmp_path / "tool" / "results.json").read_text())

    got = sl.evaluate(None, streets, view_rows=8, out=tmp_path / "python")
    assert got["results"][0]["name"] == "released model"
    assert got["results"][0]["images"] > 0 and "insertion_psnr" in got["results"][0]
    assert "budgets" in got["results"][0]  # out= runs the error-against-time sweep, as --out does
    assert without_timing(got) == without_timing(expected)
    # out= writes the tool's files, and its results.json is the dict returned.
    assert json.loads((tmp_path / "python" / "results.json").read_text()) == got
    for name in ("results.md", "error_time.png"):
        assert (tmp_path / "python" / name).exists(), name


def test_evaluate_options_are_the_tools_flags(streets, tool, released, tmp_path):
    run = subprocess.run([tool("streetlight-eval"), "--checkpoint", released, "--name", "r", "--data", str(streets),
                          "--split", "train", "--limit", "1", "--view-rows", "4", "--no-flip-average",
                          "--no-visible-sun", "--json"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    expected = json.loads(run.stdout)
    got = sl.evaluate([released], [str(streets)], names=["r"], split="train", limit=1, view_rows=4,
                      flip_average=False, visible_sun=False)
    assert "budgets" not in got["results"][0]  # no sweep without out
    assert got["results"][0]["flip_average"] is False and got["results"][0]["images"] == 1
    assert without_timing(got) == without_timing(expected)


def test_a_missing_data_folder_is_a_file_not_found_error_naming_it(tmp_path):
    with pytest.raises(FileNotFoundError, match="nothing.*is not a folder"):
        sl.evaluate(None, tmp_path / "nothing")
    assert not (tmp_path / "out").exists()


def test_bad_options_are_value_errors_with_the_librarys_message(streets, tmp_path):
    with pytest.raises(ValueError, match="--crops must be positive"):
        sl.evaluate(None, streets, crops=0)
    with pytest.raises(ValueError, match="one --name per --checkpoint"):
        sl.evaluate(None, streets, names=["a", "b"])
    with pytest.raises(ValueError, match="data: expected a path"):
        sl.evaluate(None, 3)
