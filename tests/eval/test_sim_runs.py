"""The simulator's runs measured (loosefit.eval.sim_runs): the candidate configurations,
the cache's names, the nested timer and the training data's cloth."""

from __future__ import annotations

import json
import time

import pytest

from loosefit.eval.sim_runs import (
    Timer,
    candidate_config,
    kernel_name,
    model_cloth,
    parse_candidate,
    run_key,
)
from loosefit.sim.presets import PRESETS, preset


def test_a_candidate_is_a_name_and_json_values():
    name, changes = parse_candidate('fast:substeps=10,self_contact_passes=1,device="cuda:0"')
    assert name == "fast"
    assert changes == {"substeps": 10, "self_contact_passes": 1, "device": "cuda:0"}
    assert parse_candidate("base") == ("base", {})
    assert parse_candidate("half:iterations=2.5,") == ("half", {"iterations": 2.5})


def test_a_candidate_changes_only_its_fields_of_the_preset():
    name = next(iter(PRESETS))
    base = preset(name)
    passes = 3 - base.cloth.self_contact_passes  # 1 <-> 2
    changed = candidate_config(name, {"self_contact_passes": passes})
    assert changed.cloth.self_contact_passes == passes
    fields = vars(base.cloth)
    differ = {k for k in fields if getattr(changed.cloth, k) != fields[k]}
    assert differ == {"self_contact_passes"}
    assert changed.motions == base.motions


def test_a_run_is_cached_under_its_clip_and_a_digest_of_the_rest():
    key = run_key("05_10", 60, 0, {"substeps": 10})
    assert key.startswith("05_10-60-") and len(key) == len("05_10-60-") + 10
    assert run_key("05_10", 60, 0, {"substeps": 10}) == key  # the same run, the same name
    others = {
        run_key("05_10", 61, 0, {"substeps": 10}),
        run_key("05_10", 60, 1, {"substeps": 10}),
        run_key("05_10", 60, 0, {"substeps": 11}),
        run_key("05_10", 60, 0, {}),
    }
    assert key not in others and len(others) == 4


class Clock:
    """A thing whose methods a :class:`Timer` wraps."""

    def outer(self):
        time.sleep(0.02)
        self.inner()
        return "done"

    def inner(self):
        time.sleep(0.03)


def test_the_timer_splits_nested_calls_into_their_own_time():
    timer = Timer()
    timer.wrap(Clock, "outer", "outer")
    timer.wrap(Clock, "inner", "inner")
    clock = Clock()
    assert clock.outer() == "done"
    clock.inner()
    timer.restore()
    assert timer.calls == {"outer": 1, "inner": 2}
    assert timer.total["outer"] >= 0.05
    assert timer.self_["inner"] == pytest.approx(timer.total["inner"])
    # outer's own time: its total less the inner call it made (about 0.02 s)
    assert timer.self_["outer"] == pytest.approx(
        timer.total["outer"] - (timer.total["inner"] - timer.self_["inner"]) - 0.03, abs=0.02
    )
    assert 0.015 <= timer.self_["outer"] < timer.total["outer"] - 0.025
    assert Clock.outer.__name__ == "outer" and Clock.inner.__name__ == "inner"  # restored
    assert not timer.stack


def test_a_replaced_attribute_comes_back_on_restore():
    class Owner:
        value = 1

    timer = Timer()
    timer.replace(Owner, "value", 2)
    timer.replace(Owner, "value", 3)
    assert Owner.value == 3
    timer.restore()
    assert Owner.value == 1


def test_a_kernel_is_named_by_its_key_or_its_function():
    class Kernel:
        key = "solve_particles"

    def integrate():
        pass

    assert kernel_name(Kernel()) == "solve_particles"
    assert kernel_name(integrate) == "integrate"


def test_the_cloth_of_the_training_data_from_its_manifest(tmp_path):
    cloth = {"substeps": 20, "seed": 3}
    (tmp_path / "manifest.json").write_text(json.dumps({"config": {"cloth": cloth}}))
    assert model_cloth(None, str(tmp_path)) == cloth
