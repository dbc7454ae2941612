"""The lamp bank: one Modbus coil per lamp, light sensors, optional dimmers.

Lamp *i* (the *i*-th lamp of the light arc) is switched by coil
``registers.coils + i``; discrete input ``registers.light_sensors + i`` says
whether light is actually seen, which catches a burnt-out bulb before a whole
session is captured in the dark. See ``rig.devices.LampBankRegisters``.
"""

from __future__ import annotations

from collections.abc import Iterable

from drivers.errors import DeviceError, DeviceFault
from drivers.modbus._link import ModbusLink
from drivers.registry import register
from rig.clock import Clock
from rig.config import LampBank
from rig.devices import ModbusLamps

__all__ = ["ModbusLampBank"]


class ModbusLampBank:
    """Driver of the lamp bank; satisfies ``drivers.interfaces.LampBank``.

    Parameters
    ----------
    device : ModbusLamps
        The bank's address, unit id, timeouts and retries, and where its
        coils, light sensors and dimmers start.
    lamp_ids : sequence of str
        The lamps in channel order (the light arc's lamps).
    clock : Clock
        Time for the warm-up wait and the backoff.
    warmup_s : float
        From switching a lamp on to checking its light sensor.
    name : str
        The device's name in errors.
    """

    def __init__(
        self,
        device: ModbusLamps,
        *,
        lamp_ids: Iterable[str],
        clock: Clock,
        warmup_s: float = 0.05,
        name: str = "lamp bank",
    ):
        self._ids = tuple(lamp_ids)
        if not self._ids or len(set(self._ids)) != len(self._ids):
            raise ValueError(f"{name}: lamp_ids must be unique and not empty; got {self._ids}")
        if warmup_s < 0:
            raise ValueError(f"{name}: warmup_s={warmup_s} must be ≥ 0")
        self.name = name
        self.registers = device.registers
        self._clock = clock
        self._warmup_s = warmup_s
        self._link = ModbusLink(device, device=name, clock=clock)

    @property
    def lamp_ids(self) -> tuple[str, ...]:
        return self._ids

    def switch(self, lamps_on: set[str] | frozenset[str]) -> None:
        """Light exactly ``lamps_on`` (all others off), then check what is lit.

        Raises
        ------
        DeviceError
            The coils read back differ from what was written.
        DeviceFault
            A lamp switched on stays dark (or one switched off still glows);
            the message names the lamp and its channel.
        """
        wanted = frozenset(lamps_on)
        unknown = sorted(wanted - set(self._ids))
        if unknown:
            raise ValueError(f"{self.name}: unknown lamp(s) {unknown}; this bank has {self._ids}")
        op = f"switch on {sorted(wanted)}" if wanted else "switch all off"
        coils = [lamp in wanted for lamp in self._ids]
        self._link.write_coils(self.registers.coils, coils, operation=op)
        readback = self.lamps_on(operation=op)
        if readback != wanted:
            raise DeviceError(
                self.name, op, f"coils read back {sorted(readback)} after writing {sorted(wanted)}"
            )
        if self._warmup_s:
            self._clock.sleep(self._warmup_s)
        lit = self._link.read_discrete_inputs(
            self.registers.light_sensors, len(self._ids), operation=op
        )
        for channel, (lamp, on, seen) in enumerate(zip(self._ids, coils, lit, strict=True)):
            if on and not seen:
                raise DeviceFault(
                    self.name,
                    op,
                    f"lamp {lamp!r} (channel {channel}) is switched on but its light sensor "
                    f"sees no light after {self._warmup_s} s; replace the bulb or check its wiring",
                )
            if seen and not on:
                raise DeviceFault(
                    self.name,
                    op,
                    f"lamp {lamp!r} (channel {channel}) is switched off but still lit; "
                    f"check its relay",
                )

    def lamps_on(self, *, operation: str = "read lamps") -> frozenset[str]:
        """The lamps whose coils read back on."""
        coils = self._link.read_coils(self.registers.coils, len(self._ids), operation=operation)
        return frozenset(lamp for lamp, on in zip(self._ids, coils, strict=True) if on)

    def set_level(self, lamp_id: str, level: float) -> None:
        """Dim ``lamp_id`` to ``level`` in [0, 1] (needs ``registers.dimming``)."""
        if lamp_id not in self._ids:
            raise ValueError(f"{self.name}: unknown lamp {lamp_id!r}; this bank has {self._ids}")
        if not 0.0 <= level <= 1.0:
            raise ValueError(f"{self.name}: level {level} for {lamp_id!r} must be in [0, 1]")
        op = f"dim {lamp_id!r} to {level:.3f}"
        if not self.registers.dimming:
            raise DeviceError(self.name, op, "this bank has no dimmers (registers.dimming = false)")
        channel = self._ids.index(lamp_id)
        value = round(level * self.registers.dim_full_scale)
        self._link.write_holding(self.registers.dimmers + channel, [value], operation=op)

    def level(self, lamp_id: str) -> float:
        """A lamp's dimming level in [0, 1] as the bank reports it."""
        if lamp_id not in self._ids:
            raise ValueError(f"{self.name}: unknown lamp {lamp_id!r}; this bank has {self._ids}")
        op = f"read level of {lamp_id!r}"
        if not self.registers.dimming:
            raise DeviceError(self.name, op, "this bank has no dimmers (registers.dimming = false)")
        channel = self._ids.index(lamp_id)
        value = self._link.read_holding(self.registers.dimmers + channel, 1, operation=op)[0]
        return value / self.registers.dim_full_scale

    def close(self) -> None:
        """Close the connection; idempotent. Lamps keep their state."""
        self._link.close()


@register("lamp_bank", "modbus")
def open_lamp_bank(section: LampBank, *, clock: Clock, lamp_ids: Iterable[str]) -> ModbusLampBank:
    """The lamp bank of a rig config; ``lamp_ids``: the light arc's lamps, in channel order."""
    return ModbusLampBank(section.device, lamp_ids=lamp_ids, clock=clock, warmup_s=section.warmup_s)
