"""The add-on's render properties are made from the option registry (``core.options.OPTIONS``):
the same labels, tooltips, menus (identifiers, labels, descriptions), defaults and ranges (the
UI may narrow a range, never widen it), and they read back as the core's values."""

import importlib

import pytest

from scenes import ADDON_MODULE


@pytest.fixture(scope="module")
def modules(addon):
    """The add-on's own copies of the registry, the render settings and the properties."""
    return {name: importlib.import_module(f"{ADDON_MODULE}.{path}") for name, path in (
        ("options", "core.options"), ("render", "core.render"),
        ("properties", "addon.properties"))}


def _ui_options(props, options):
    return [o for o in options.OPTIONS.values() if o.prop_name in props.bl_rna.properties]


def test_every_render_option_but_threads_has_a_property(empty_scene, modules):
    props = empty_scene.sampling_lab
    names = {o.name for o in _ui_options(props, modules["options"])}
    assert names == set(modules["options"].OPTIONS) - {"threads"}


def test_property_labels_tooltips_and_defaults_are_the_registrys(empty_scene, modules):
    props = empty_scene.sampling_lab
    for option in _ui_options(props, modules["options"]):
        prop = props.bl_rna.properties[option.prop_name]
        assert (prop.name, prop.description) == (option.label, option.description), option.name
        if option.choices:
            assert prop.default == option.default.upper(), option.name
        else:
            assert prop.default == pytest.approx(option.default), option.name


def test_menus_are_the_registrys_choices_in_order(empty_scene, modules):
    props = empty_scene.sampling_lab
    for option in _ui_options(props, modules["options"]):
        if not option.choices:
            continue
        items = [(i.identifier, i.name, i.description)
                 for i in props.bl_rna.properties[option.prop_name].enum_items]
        assert items == [(c.identifier, c.label, c.description) for c in option.choices], \
            option.name


def test_number_ranges_lie_within_the_registrys(empty_scene, modules):
    props = empty_scene.sampling_lab
    for option in _ui_options(props, modules["options"]):
        if option.choices or option.kind is bool:
            continue
        prop = props.bl_rna.properties[option.prop_name]
        # Every value the UI allows passes the core's check (floats in single precision).
        option.check(option.kind(prop.hard_min))
        if option.maximum is not None:
            option.check(option.kind(prop.hard_max))
        assert prop.hard_min >= option.minimum * (1 - 1e-6), option.name


def test_properties_read_back_as_core_values(empty_scene, modules):
    props = empty_scene.sampling_lab
    defaults = modules["render"].RenderSettings()
    values = modules["properties"].core_values(props)
    # Workers: the add-on's final renders use processes, the core's default is threads (a
    # patched core function would not reach a worker process: see RenderSettings).
    assert (values.pop("workers"), defaults.workers) == ("processes", "threads")
    for name, value in values.items():
        assert value == pytest.approx(getattr(defaults, name)), name
    props.filter_type, props.mis_heuristic, props.use_strategy_views = 'BOX', 'CUTOFF', True
    values = modules["properties"].core_values(props)
    assert (values["filter_type"], values["mis_heuristic"], values["strategy_views"]) == (
        "box", "cutoff", True)
    modules["options"].validate(modules["render"].RenderSettings(**values))
