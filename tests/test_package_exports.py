"""The public names of the package contract (issue 3, "Public names") resolve lazily."""

import subprocess
import sys

import bmg160_emu


def test_every_public_name_resolves_to_an_object_of_that_name():
    for name in bmg160_emu.__all__:
        if name == "__version__":
            continue
        value = getattr(bmg160_emu, name)
        assert getattr(value, "__name__", name) == name


def test_all_lists_exactly_the_lazy_exports():
    assert set(bmg160_emu.__all__) == set(bmg160_emu._EXPORTS) | {"__version__"}


def test_unknown_attribute_is_an_attribute_error():
    try:
        bmg160_emu.NoSuchThing  # noqa: B018
    except AttributeError as exc:
        assert "NoSuchThing" in str(exc)
    else:
        raise AssertionError("expected AttributeError")


def test_importing_the_package_does_not_import_numpy():
    # A cheap import: the chip and the noise engine load only when a name is used.
    code = "import sys, bmg160_emu; print('numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
