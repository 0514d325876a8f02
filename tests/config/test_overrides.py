from dataclasses import dataclass

import pytest

from pasta.config.overrides import build, build_many
from pasta.core import ConfigError


@dataclass
class Loop:
    epochs: int = 1
    lr: float = 0.5


@dataclass
class Module:
    flag: bool = False
    name: str = "a"
    out: str | None = None


def test_values_are_typed_and_routed_to_their_dataclass():
    loop, module = build_many(["epochs=3", "lr=0.25", "flag=true", "name=b", "out=/tmp/x"], [Loop, Module])
    assert loop == Loop(3, 0.25) and module == Module(True, "b", "/tmp/x")
    assert build(Loop, {"epochs": 7}) == Loop(7, 0.5)


def test_unknown_key_names_command_and_closest_key():
    with pytest.raises(ConfigError, match=r"unknown key 'epoch' for `pasta train vae`; did you mean 'epochs'\?"):
        build_many(["epoch=3"], [Loop, Module], command="pasta train vae")


def test_bad_value_and_malformed_item():
    with pytest.raises(ConfigError, match="^epochs=three: must be an integer$"):
        build_many(["epochs=three"], [Loop])
    with pytest.raises(ConfigError, match="^flag=maybe for `pasta x`: must be true or false$"):
        build_many(["flag=maybe"], [Module], command="pasta x")
    for value in ("nan", "inf", "-1e400"):
        with pytest.raises(ConfigError, match="^lr=.*: must be a finite number$"):
            build_many([f"lr={value}"], [Loop])
    with pytest.raises(ConfigError, match=r"^epochs=\$\{seed\}: \$\{...\} interpolations are not supported"):
        build_many(["epochs=${seed}"], [Loop])
    with pytest.raises(ConfigError, match="must look like key=value"):
        build_many(["epochs"], [Loop])
