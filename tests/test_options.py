"""Command-line options derived from config dataclasses: the option's default is the field's, written once."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import pytest

from app.cli import OneLineParser, build_parser
from app.options import add_options, config_from
from app.turntable import TurntableConfig
from models.training.config import DistillConfig, TrainConfig
from renderer.dataset_config import DataConfig


@dataclass(frozen=True)
class Sample:
    count: int = field(default=3, metadata={"help": "how many"})
    names: tuple[str, ...] = field(default=("a", "b"), metadata={"help": "names", "comma": True})
    inputs: tuple[str, ...] = field(default=(), metadata={"help": "inputs", "required": True})
    kept: bool = field(default=True, metadata={"help": "drop it", "flag": "--no-kept"})
    loud: bool = field(default=False, metadata={"help": "say more"})
    mode: str = field(default="x", metadata={"help": "mode", "choices": ("x", "y")})
    size: int | None = field(default=None, metadata={"help": "side", "flag": "--side"})
    internal: int = 7  # no help: not an option


def parse(argv: list[str]):
    parser = OneLineParser(prog="sample")
    add_options(parser, Sample)
    return config_from(Sample, parser.parse_args(argv))


def test_fields_become_options_with_their_defaults_types_and_flags():
    assert parse(["--inputs", "i"]) == Sample(inputs=("i",))
    chosen = parse(["--inputs", "i", "j", "--count", "5", "--names", "p, q,", "--no-kept", "--loud", "--mode", "y",
                    "--side", "64"])
    assert chosen == Sample(count=5, names=("p", "q"), inputs=("i", "j"), kept=False, loud=True, mode="y", size=64)


@pytest.mark.parametrize("argv", [[], ["--inputs", "i", "--count", "many"], ["--inputs", "i", "--mode", "z"],
                                  ["--inputs", "i", "--internal", "3"]])
def test_a_bad_or_unknown_option_is_one_line_and_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as exit_:
        parse(argv)
    assert exit_.value.code == 2 and len(capsys.readouterr().err.strip().splitlines()) == 1


@pytest.mark.parametrize("command, config_type, fixed", [
    (["train", "--out", "o", "--data", "d"], TrainConfig, {"architecture": "nvr_plus", "precision": "fp32"}),
    (["distill", "--model", "m", "--out", "o"], DistillConfig, {}),
    (["data", "generate", "--out", "o", "--objects", "4"], DataConfig, {}),
    (["turntable", "s.json", "-o", "o.gif"], TurntableConfig, {}),
])
def test_each_commands_defaults_are_its_configs(command, config_type, fixed):
    """What a command builds from its defaults equals the config built from the dataclass's own defaults."""
    args = build_parser().parse_args(command)
    given = {f.name: getattr(args, f.name) for f in dataclasses.fields(config_type) if f.metadata.get("required")}
    given = {name: tuple(value) if isinstance(value, list) else value for name, value in given.items()}
    assert config_from(config_type, args, **fixed) == config_type(**given, **fixed)
