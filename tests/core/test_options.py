"""One registry of render options (``core.options.OPTIONS``): the render settings, the core's
validation and the command line are all made from it, and a bad value's message names the
option and what it allows. (The add-on's properties: ``tests/addon/test_options_ui.py``.)"""

from __future__ import annotations

import argparse
import dataclasses
import re

import pytest

from sampling_lab import cli
from sampling_lab.core import options
from sampling_lab.core.integrators import INTEGRATORS
from sampling_lab.core.lights import LIGHT_SAMPLINGS, LIGHT_SELECTIONS
from sampling_lab.core.options import OPTIONS, Choice, Option, validate
from sampling_lab.core.render import RenderSettings, check_settings
from sampling_lab.core.sampling.distributions import DISTRIBUTION_METHODS
from sampling_lab.core.sampling.mis import MIS_SETTINGS
from sampling_lab.core.sampling.samplers import available
from sampling_lab.core.scenes import cornell_box


def _render_actions():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    render = sub.choices["render"]
    return parser, sub, render, {s: a for a in render._actions for s in a.option_strings}


def test_every_render_setting_is_a_registry_option_with_its_default():
    fields = {f.name: f.default for f in dataclasses.fields(RenderSettings) if f.name != "region"}
    assert list(fields) == list(OPTIONS)
    # Workers: the core's default is threads, the product's (add-on, CLI) processes, so that a
    # test patching a core function renders in the process it patched (RenderSettings).
    assert (fields.pop("workers"), OPTIONS["workers"].default) == ("threads", "processes")
    for name, default in fields.items():
        assert default == OPTIONS[name].default, name
        OPTIONS[name].check(default)


def test_menus_are_the_core_lists_with_a_label_and_description_each():
    expected = {"integrator": INTEGRATORS, "mis_heuristic": MIS_SETTINGS,
                "light_selection": LIGHT_SELECTIONS, "light_sampling": LIGHT_SAMPLINGS,
                "distribution": DISTRIBUTION_METHODS, "sampler": available()}
    for name, values in expected.items():
        assert set(OPTIONS[name].values) == set(values), name
    for option in OPTIONS.values():
        assert option.description and option.label, option.name
        for choice in option.choices:
            assert choice.value == choice.value.lower() and choice.identifier == choice.value.upper()
            assert choice.label and len(choice.description) > 20, (option.name, choice.value)


def test_menu_texts_that_name_no_core_value_fail_at_import():
    with pytest.raises(RuntimeError, match="do not match"):
        options._choices(("cdf", "alias"), {"cdf": ("CDF", "...")})


def test_filter_type_is_lower_case_and_only_what_the_film_implements():
    assert OPTIONS["filter_type"].values == ("box", "blackman_harris")
    assert RenderSettings().filter_type == "blackman_harris"
    scene = cornell_box(4, 4)
    for bad in ("gaussian", "BLACKMAN_HARRIS"):
        with pytest.raises(ValueError, match=f"filter_type: '{bad}' is not one of box, "
                                             f"blackman_harris"):
            check_settings(scene, RenderSettings(filter_type=bad))


@pytest.mark.parametrize("name", [n for n, o in OPTIONS.items() if o.choices])
def test_a_bad_menu_value_names_the_option_and_the_allowed_values(name):
    with pytest.raises(ValueError) as err:
        validate(RenderSettings(**{name: "no_such_value"}))
    assert str(err.value) == (f"{name}: 'no_such_value' is not one of "
                              f"{', '.join(OPTIONS[name].values)}")


@pytest.mark.parametrize("name, value, allowed", [
    ("mis_beta", 0.0, "[0.01, 100]"), ("mis_alpha", 1.5, "[0, 1]"), ("spp", -1, "[0, 16777216]"),
    ("spp", 2.5, "[0, 16777216]"), ("max_bounces", 2000, "[0, 1024]"),
    ("strategy_max_length", 9, "[1, 8]"), ("filter_width", float("nan"), "[0.01, 10]"),
    ("time_limit", -1.0, "[0, inf]"), ("seed", -3, "[0, 2147483647]")])
def test_a_number_out_of_range_names_the_option_and_its_range(name, value, allowed):
    with pytest.raises(ValueError, match=re.escape(f"{name}: {value!r} is not ")) as err:
        validate(RenderSettings(**{name: value}))
    assert str(err.value).endswith(f"in {allowed}")


def test_a_switch_takes_only_true_or_false():
    with pytest.raises(ValueError, match="strategy_views: 1 is not one of True, False"):
        validate(RenderSettings(strategy_views=1))


def test_an_unlimited_time_is_a_valid_time_limit():
    validate(RenderSettings(spp=0, time_limit=float("inf")))


def test_render_flags_take_their_values_help_and_defaults_from_the_registry():
    _, _, _, actions = _render_actions()
    for name, option in OPTIONS.items():
        action = actions[option.flag_name]
        assert option.description.replace("%", "%%") in action.help, name
        default = option.default
        if option.kind is bool:
            default = "on" if option.default else "off"
        assert f"(default: {default};" in action.help, name
        if option.choices:
            assert f"one of {', '.join(option.values)}" in action.help, name
            assert action.type(option.default.upper()) == option.default, name


def test_a_registry_change_reaches_the_command_line_and_validation(monkeypatch):
    old = OPTIONS["distribution"]
    extra = Choice("bisection", "Bisection", "A menu entry that exists only in this test")
    monkeypatch.setitem(OPTIONS, "distribution", dataclasses.replace(
        old, choices=old.choices + (extra,), description="Changed in the test"))
    _, _, _, actions = _render_actions()
    action = actions["--distribution"]
    assert "Changed in the test" in action.help and "bisection" in action.help
    assert action.type("bisection") == "bisection"
    validate(RenderSettings(distribution="bisection"))
    monkeypatch.setitem(OPTIONS, "distribution", dataclasses.replace(old, choices=old.choices[:1]))
    with pytest.raises(ValueError, match="distribution: 'alias' is not one of cdf$"):
        validate(RenderSettings(distribution="alias"))
    with pytest.raises(argparse.ArgumentTypeError, match="distribution: 'alias' is not one"):
        _render_actions()[3]["--distribution"].type("alias")


@pytest.mark.parametrize("argv, message", [
    (["--mis", "veach"], "argument --mis: mis_heuristic: 'veach' is not one of power, "),
    (["--mis-beta", "0"], "argument --mis-beta: mis_beta: 0.0 is not a number in [0.01, 100]"),
    (["--mis-beta", "two"], "argument --mis-beta: mis_beta: 'two' is not a number in "),
    (["--filter-type", "gaussian"], "filter_type: 'gaussian' is not one of box, blackman_harris"),
    (["--seed", "-1"], "argument --seed: seed: -1 is not an integer in [0, 2147483647]"),
])
def test_a_bad_flag_value_exits_2_with_the_registry_message(argv, message, tmp_path, capsys):
    code = cli.main(["render", "cornell", "-o", str(tmp_path / "a.exr"), *argv])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("sampling_lab: error: ") and message in err, err
    assert len(err.splitlines()) == 1


def test_every_option_of_every_command_has_help_that_shows_its_default():
    _, sub, _, _ = _render_actions()
    for command, parser in sub.choices.items():
        formatter = parser.formatter_class(prog=parser.prog)
        for action in parser._actions:
            if (not action.option_strings or action.required
                    or isinstance(action, argparse._HelpAction)):
                continue
            assert action.help, (command, action.option_strings)
            assert "default" in formatter._get_help_string(action), (command,
                                                                     action.option_strings)
        assert "%(" not in parser.format_help(), command


def test_every_subcommand_has_a_one_line_description_and_one_program_name():
    parser, sub, _, _ = _render_actions()
    assert parser.prog == cli.PROG == "sampling_lab"
    assert parser.description == cli.DESCRIPTION and parser.description not in cli.__doc__
    helps = {a.dest: a.help for a in sub._choices_actions}
    assert set(helps) == set(sub.choices)
    for command, parser_ in sub.choices.items():
        assert helps[command] and "\n" not in helps[command], command
        assert parser_.description and "\n" not in parser_.description, command
        assert parser_.format_usage().startswith(f"usage: sampling_lab {command} "), command


def test_usage_errors_name_the_same_program_as_the_usage(capsys):
    assert cli.main(["render"]) == 2
    assert capsys.readouterr().err.startswith("sampling_lab: error: ")


def test_option_records_are_values():
    option = OPTIONS["mis_heuristic"]
    assert isinstance(option, Option) and option.flag_name == "--mis"
    assert option.prop_name == "mis_heuristic" and OPTIONS["spp"].prop_name == "samples"
    with pytest.raises(dataclasses.FrozenInstanceError):
        option.default = "balance"
