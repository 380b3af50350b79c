"""``loosefit train STAGE``: each stage takes its own flags and refuses another stage's,
naming the stage it belongs to (the parser only: nothing trains here)."""

import pytest

from loosefit.cli import build_parser, main
from loosefit.cli import train as cli_train

# every flag each stage takes beyond the common ones, with a value to give it
OWN = {
    "generative": {
        "--decoder": "vertex",
        "--precision": "bf16",
        "--membrane": "10",
        "--bending": "0.5",
        "--collision": "30",
        "--kl": "1e-4",
        "--mirror": None,
        "--basis-size": "64",
        "--init": "g.pt",
    },
    "motion": {
        "--generative": "g.pt",
        "--no-previous-state": None,
        "--previous": "teacher",
        "--mirror": None,
        "--joints": "lower",
        "--precision": "bf16",
        "--membrane": "10",
        "--bending": "0.5",
        "--collision": "30",
        "--flare": "1",
        "--speed": "10",
        "--unroll": None,
        "--init": "m.pt",
    },
    "detail": {
        "--motion": "m.pt",
        "--generative": "g.pt",
        "--no-discriminator": None,
        "--edge-weight": "10",
        "--init": "d.pt",
    },
    "baseline": {
        "--method": "virtual-bones",
        "--bones": "12",
        "--mirror": None,
        "--joints": "lower",
    },
}
COMMON = {
    "--data": "datasets/x",
    "--preset": "full",
    "--out": "runs/x",
    "--epochs": "3",
    "--batch-size": "4",
    "--lr": "1e-4",
    "--max-frames": "8",
    "--device": "cuda",
    "--seed": "7",
    "--threads": "1",
}
RUNS = {
    "generative": cli_train.run_generative,
    "motion": cli_train.run_motion,
    "detail": cli_train.run_detail,
    "baseline": cli_train.run_baseline,
}


def _argv(flags: dict) -> list[str]:
    return [t for flag, value in flags.items() for t in (flag, value) if t is not None]


@pytest.mark.parametrize("stage", list(OWN))
def test_each_stage_takes_its_own_flags_and_the_common_ones(stage):
    args = build_parser().parse_args(["train", stage, *_argv(OWN[stage]), *_argv(COMMON)])
    assert args.command == "train" and args.stage == stage and args.func is RUNS[stage]
    assert args.data == "datasets/x" and args.epochs == 3 and args.lr == 1e-4
    assert args.threads == 1 and args.seed == 7 and args.device == "cuda"
    for flag, value in OWN[stage].items():
        got = getattr(args, flag[2:].replace("-", "_"))
        if value is None:  # a switch
            assert got is True, flag
        else:
            assert str(got) == value or got == float(value), flag


@pytest.mark.parametrize("stage", list(OWN))
def test_a_stage_s_defaults_are_the_flat_parser_s(stage):
    args = build_parser().parse_args(["train", stage])
    assert (args.data, args.preset, args.out, args.device, args.threads) == (
        "datasets/demo",
        "cpu",
        None,
        "cpu",
        0,
    )
    assert args.epochs is args.batch_size is args.lr is args.max_frames is args.seed is None
    defaults = {"--decoder": "decomposed", "--mirror": False, "--unroll": False}
    for flag in OWN[stage]:
        value = getattr(args, flag[2:].replace("-", "_"))
        assert value == defaults.get(flag, False if flag.startswith("--no-") else None), flag
    # a flag the stage lacks is not in its namespace at all (not silently None)
    for other in set().union(*OWN.values()) - set(OWN[stage]):
        assert not hasattr(args, other[2:].replace("-", "_")), other


def test_motion_refuses_no_discriminator_naming_train_detail(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["train", "motion", "--generative", "g.pt", "--no-discriminator"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "--no-discriminator belongs to `loosefit train detail`" in err
    assert "not to `loosefit train motion`" in err


@pytest.mark.parametrize("stage", list(OWN))
def test_every_flag_of_another_stage_is_refused_naming_the_stages_that_take_it(stage, capsys):
    others = {flag for s in OWN if s != stage for flag in OWN[s]} - set(OWN[stage])
    assert others
    for flag in sorted(others):
        value = next(OWN[s][flag] for s in OWN if flag in OWN[s])
        with pytest.raises(SystemExit):
            build_parser().parse_args(["train", stage, *_argv({flag: value})])
        err = capsys.readouterr().err
        owners = [s for s in OWN if flag in OWN[s]]
        assert f"{flag} belongs to " in err, err
        assert all(f"`loosefit train {s}`" in err for s in owners), err
        assert f"not to `loosefit train {stage}`" in err, err


def test_a_flag_with_its_value_after_an_equals_sign_is_refused_alike(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["train", "detail", "--precision=fp32"])
    err = capsys.readouterr().err
    assert "--precision belongs to `loosefit train generative` and `loosefit train motion`" in err


def test_a_flag_before_the_stage_asks_for_the_stage_first(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["train", "--data", "d", "motion"])
    err = capsys.readouterr().err
    assert "--data belongs to" in err and "name the stage first" in err
    with pytest.raises(SystemExit):
        build_parser().parse_args(["train"])
    assert "STAGE" in capsys.readouterr().err


def test_the_refused_flags_are_not_in_a_stage_s_help(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["train", "motion", "--help"])
    out = capsys.readouterr().out
    assert "--flare" in out and "--mirror" in out
    assert "--no-discriminator" not in out and "--method" not in out and "--kl" not in out


@pytest.mark.parametrize("stage", ["detail", "baseline"])
def test_torchrun_runs_the_generative_and_motion_stages_only(stage, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("WORLD_SIZE", "2")
    flags = {"detail": ["--motion", "x.pt"], "baseline": ["--method", "santesteban"]}[stage]
    assert main(["train", stage, *flags, "--out", str(tmp_path / stage)]) == 2
    err = capsys.readouterr().err
    assert "torchrun" in err and "generative or motion" in err
    assert not (tmp_path / stage).exists()


def test_motion_flags_reach_its_configuration(monkeypatch, tmp_path):
    import loosefit.api as api

    seen = {}

    def capture(cfg, data, generative, out, **kw):
        seen["cfg"] = cfg
        return {}

    monkeypatch.setattr(api, "train_motion", capture)
    monkeypatch.setattr(cli_train, "_finish", lambda out, report, kept="model": 0)
    argv = ["train", "motion", "--generative", "g.pt", "--out", str(tmp_path)]
    main([*argv, "--unroll", "--speed", "10", "--flare", "1", "--collision", "30"])
    cfg = seen["cfg"]
    assert cfg.unroll is True and cfg.loss.speed == 10.0 and cfg.loss.flare == 1.0
    assert cfg.loss.collision == 30.0
    main(argv)
    assert seen["cfg"].unroll is False and seen["cfg"].loss.speed == 0.0


def test_generative_flags_reach_its_configuration(monkeypatch, tmp_path, capsys):
    import loosefit.api as api

    seen = {}

    def capture(cfg, data, out, **kw):
        seen["cfg"] = cfg
        return {}

    monkeypatch.setattr(api, "train_generative", capture)
    monkeypatch.setattr(cli_train, "_finish", lambda out, report, kept="model": 0)
    argv = ["train", "generative", "--out", str(tmp_path)]
    main([*argv, "--kl", "1e-4", "--collision", "30"])
    assert seen["cfg"].loss.kl == 1e-4 and seen["cfg"].loss.collision == 30.0
    assert seen["cfg"].mirror is False
    main([*argv, "--mirror", "--decoder", "basis", "--basis-size", "64"])
    assert seen["cfg"].mirror is True
    assert seen["cfg"].model.decoder == "basis" and seen["cfg"].model.basis_size == 64
    main(argv)
    assert seen["cfg"].loss.kl == 1e-3  # the paper's lambda_3
    assert main([*argv, "--kl", "-1"]) != 0
    assert "field 'kl': expected a number >= 0, found -1.0" in capsys.readouterr().err
