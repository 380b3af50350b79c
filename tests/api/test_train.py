"""The training stages through the API: a stage's configuration from a preset, and a stage
trained into a run folder that loosefit.load then opens."""

from __future__ import annotations

import pytest

from loosefit.api import TRAINING_STAGES, train_generative, training_config
from loosefit.errors import LoosefitInputError


@pytest.mark.parametrize("stage", TRAINING_STAGES)
def test_every_stage_has_its_configuration_from_a_preset(stage):
    from loosefit.train.loop import TrainerConfig

    config = training_config(stage, "cpu", epochs=3)
    assert isinstance(config, TrainerConfig) and config.epochs == 3
    assert type(config).__name__ == f"Train{stage.capitalize()}Config"


def test_a_stage_a_preset_or_a_field_it_has_not_is_refused():
    with pytest.raises(LoosefitInputError, match=r"stage.*generative or motion.*'shading'"):
        training_config("shading", "cpu")
    with pytest.raises(LoosefitInputError, match="preset"):
        training_config("motion", "enormous")
    with pytest.raises(LoosefitInputError, match="a field of it or of its model"):
        training_config("baseline", "cpu", colour="red")


def test_a_model_field_goes_to_the_model_s_configuration():
    config = training_config("generative", "cpu", decoder="ssdr")
    assert config.model.decoder == "ssdr"


def test_train_generative_writes_a_run_that_the_motion_stage_can_record(toy_dataset, tmp_path):
    from loosefit.inference.checkpoints import GENERATIVE_FORMAT, checkpoint_format

    config = training_config("generative", "cpu", epochs=1, eval_every=1000)
    config.model.uv_size, config.model.channels = 32, (4, 8, 8, 8)
    config.model.rec_hidden = (16, 16, 16)
    report = train_generative(config, toy_dataset, tmp_path / "g", log=lambda *_: None)
    assert report and (tmp_path / "g" / "report.md").is_file()
    assert checkpoint_format(tmp_path / "g" / "checkpoint.pt") == GENERATIVE_FORMAT
