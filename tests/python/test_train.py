# streetlight.train: a dict config trains two steps of a tiny sky-autoencoder config, and a resumed
# run continues bit-identically to an uninterrupted one (train/trainer.h).
import pytest

import streetlight as sl


def tiny_sky_config(steps):
    # The tiny sky model of tests/support/tiny_model.h on procedural skies.
    return {
        "stage": "sky_autoencoder",
        "model": {"sky": {"height": 8, "width": 32, "code_dim": 12, "base_channels": 4, "hidden": 16,
                          "sun_lobe_texels": 1.0}},
        "data": {"val_size": 2, "pano_rays": 64},
        "train": {"steps": steps, "batch_size": 2, "log_every": 1, "val_every": 2, "checkpoint_every": 2,
                  "image_every": 100},
        "optim": {"warmup_steps": 0},
    }


class StopHere(Exception):
    pass


def run(config, out, resume=None, stop_at=None):
    """Trains, collecting each step's loss; stop_at ends the run after that step from the callback."""
    losses = {}

    def progress(stage, step, terms):
        assert stage == "sky_autoencoder"
        losses[step] = terms["loss"]
        if step == stop_at:
            raise StopHere()

    if stop_at is None:
        return sl.train(config, out=str(out), resume=resume, progress=progress), losses
    with pytest.raises(StopHere):
        sl.train(config, out=str(out), resume=resume, progress=progress)
    return None, losses


def test_dict_config_trains_two_steps_and_resumes_bit_identically(tmp_path):
    _, first = run(tiny_sky_config(4), tmp_path / "a", stop_at=2)
    assert sorted(first) == [1, 2]
    assert (tmp_path / "a" / "last.safetensors").exists()
    summary, resumed = run(tiny_sky_config(4), tmp_path / "a", resume=str(tmp_path / "a" / "last.safetensors"))
    assert summary["steps"] == 4 and sorted(resumed) == [3, 4]
    _, straight = run(tiny_sky_config(4), tmp_path / "b")
    assert [straight[s] for s in (1, 2, 3, 4)] == [first[1], first[2], resumed[3], resumed[4]]


def test_unknown_config_key_is_a_value_error_naming_the_nearest_key(tmp_path):
    config = tiny_sky_config(2)
    config["train"]["stepz"] = 3
    with pytest.raises(ValueError, match=r"train\.stepz.*train\.steps"):
        sl.train(config, out=str(tmp_path / "x"))


def test_missing_config_file_is_a_file_not_found_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="nowhere.json"):
        sl.train(str(tmp_path / "nowhere.json"))


def test_an_exception_in_the_progress_callback_stops_the_run(tmp_path):
    def progress(stage, step, terms):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        sl.train(tiny_sky_config(4), out=str(tmp_path / "c"), progress=progress)
    assert (tmp_path / "c" / "last.safetensors").exists()
