"""KindRegistry: registration, refusals and discovery of a package's modules."""

import sys

import pytest

from rig.registry import KindRegistry


def test_registered_entry_is_found_and_others_are_not():
    registry = KindRegistry("json", ["turntable"])

    @registry.register("turntable", "modbus")
    def opener():
        return "opened"

    assert registry.lookup("turntable", "modbus") is opener
    assert registry.lookup("turntable", "canopen") is None
    assert registry.served("turntable") == ["modbus"]


def test_an_unregistered_entry_is_gone_and_may_be_registered_again():
    registry = KindRegistry("json", ["turntable"])
    registry.register("turntable", "modbus")(lambda: 1)
    registry.unregister("turntable", "modbus")
    assert registry.lookup("turntable", "modbus") is None
    registry.register("turntable", "modbus")(lambda: 2)
    assert registry.lookup("turntable", "modbus")() == 2


def test_unknown_role_and_double_registration_are_refused():
    registry = KindRegistry("json", ["turntable"])
    with pytest.raises(ValueError, match="unknown role 'arm'"):
        registry.register("arm", "ur")
    registry.register("turntable", "modbus")(lambda: 1)
    with pytest.raises(ValueError, match="registered twice"):
        registry.register("turntable", "modbus")(lambda: 2)


def test_first_miss_imports_the_package_modules(tmp_path, monkeypatch):
    package = tmp_path / "family_pkg"
    package.mkdir()
    (package / "__init__.py").write_text("from family_pkg._reg import REGISTRY\n")
    (package / "_reg.py").write_text(
        "from rig.registry import KindRegistry\n"
        "REGISTRY = KindRegistry('family_pkg', ['lamp_bank'])\n"
    )
    (package / "relays.py").write_text(
        "from family_pkg._reg import REGISTRY\n"
        "@REGISTRY.register('lamp_bank', 'relays')\ndef start():\n    return 'relays'\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        import family_pkg

        assert family_pkg.REGISTRY.served("lamp_bank") == ["relays"]  # listing discovers
        assert family_pkg.REGISTRY.lookup("lamp_bank", "relays")() == "relays"
    finally:
        for name in [n for n in sys.modules if n.startswith("family_pkg")]:
            del sys.modules[name]
