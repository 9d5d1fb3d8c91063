"""EV drive: NET-IN start/stop per the NET-X function assignment, speed ramps, alarms.

* NET-IN (1400h) bit i switches the function assigned to NET-X i (09-01..09-08, 0900h-0907h;
  the values in effect are the ones applied at Configuration, 0A27h). Always ON Input 1
  (06-07, 0606h) adds one function that is always ON.
* SC mode (02-01 = 0): START/STOP runs the motor, CCW/CW ON turns it counter-clockwise.
  CC mode (02-01 = 1): FWD runs clockwise, REV counter-clockwise, both ON stop.
  STOP stops; STOP-MODE ON makes a stop immediate instead of a deceleration; FREE and EBRAKE
  stop the motor at once (motor_state FREE / EBRAKE); ALM-RST and EBRAKE/ALM-RST reset an alarm.
* M0-M2 select digital operation data No.0-7; the motor speed ramps toward the selected
  digital speed (RAM twin 3F08h..., loaded from the EEPROM values at power-up and updated when
  the EEPROM value is written) at the selected acceleration/deceleration time, which is the time
  for 0..3000 r/min (0.1 s units).
* An alarm (alarm_no != 0) puts the motor in FAULT and is pushed into the alarm history;
  writing 1 to Alarm Reset (0A00h) clears it. 0A22h / 0A26h clear the alarm / communication
  error histories.
* Communication timeout (Tb1, 001 §1.3): when the time between two queries to a unit exceeds
  09-12 RS-485 communication timeout (ms; 0 = no monitoring; the fixed RS-232 unit 17 uses 09-14),
  the drive records communication error 85h (001 §4.5) and acts as 09-10 says (0: alarm,
  1: NET-IO state cleared, 2: both). Monitoring starts with the first query (the manual speaks of
  the interval between queries); any well-formed request addressed to the unit, or a broadcast,
  is a query; it is raised once per silence. The alarm number is not in this document (the
  alarm list is in PGNUM-033): the alarm puts the motor in FAULT and leaves alarm_no at 0 unless
  ``Ev(comm_timeout_alarm_no=N)`` gives one; Alarm Reset clears it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from drivemap.runtime.sim.behaviours import Behaviour, register

if TYPE_CHECKING:
    from drivemap.runtime.sim.view import UnitView as Unit

# MotorState
STOP, RUN, EBRAKE, FREE, FAULT = 0, 2, 3, 4, 5
# MotorDirection
CW, CCW = 0, 1
# NetInputFunction
F_START_STOP, F_CCW_CW, F_FREE, F_STOP_MODE, F_EBRAKE_ALM_RST, F_ALM_RST = 1, 2, 5, 6, 7, 8
F_M0, F_M1, F_M2, F_EBRAKE, F_STOP = 10, 11, 12, 13, 17
#: Acceleration/deceleration times are the time for a change of 3000 r/min.
RAMP_SPAN_RPM = 3000.0
_TWINS = ("digital_speed", "digital_accel_time", "digital_decel_time", "digital_torque_limit", "digital_duty")
#: CommErrorAction (09-10)
ACTION_ALARM, ACTION_NET_IO_CLEAR, ACTION_BOTH = 0, 1, 2
#: The unit id of the RS-232 port (fixed, 001 §1 note 2): watched with 09-14 instead of 09-12.
RS232_UNIT = 17


def _count(unit: Unit, name: str) -> int:
    return unit.spec.register(name).count if _is_array(unit, name) else 0


def _is_array(unit: Unit, name: str) -> bool:
    return unit.has(f"{name}[0]")


@register("ev")
class Ev(Behaviour):
    def __init__(self, comm_timeout_alarm_no: int | None = None) -> None:
        #: alarm_no shown by the communication-timeout alarm (not in 001; None: alarm_no stays 0)
        self.comm_timeout_alarm_no = comm_timeout_alarm_no

    def on_start(self, unit: Unit) -> None:
        for base in _TWINS:
            ram = f"{base}_ram"
            for i in range(min(_count(unit, base), _count(unit, ram))):
                if f"{ram}[{i}]" in unit.unset:  # no default, saved or preset value: loaded from EEPROM
                    unit.set_raw(f"{ram}[{i}]", unit.raw(f"{base}[{i}]"))
        unit.scratch["speed"] = float(unit.raw("motor_speed")) if unit.has("motor_speed") else 0.0
        unit.scratch["functions"] = set()
        self._update(unit, 0.0)

    # ---- inputs -------------------------------------------------------------------------
    def _functions(self, unit: Unit) -> set[int]:
        on: set[int] = set()
        net_in = unit.raw("net_in") if unit.has("net_in") else 0
        for i in range(_count(unit, "net_x_input_function")):
            if net_in >> i & 1:
                on.add(unit.effective_raw(f"net_x_input_function[{i}]"))
        if unit.has("always_on_input_1") and unit.raw("always_on_input_1"):
            on.add(unit.effective_raw("always_on_input_1"))
        return on

    def _cc_mode(self, unit: Unit) -> bool:
        return unit.has("sc_cc_mode") and unit.effective_raw("sc_cc_mode") == 1

    def _selected(self, unit: Unit, on: set[int]) -> int:
        return (F_M0 in on) + 2 * (F_M1 in on) + 4 * (F_M2 in on)

    def _data(self, unit: Unit, base: str, no: int, fallback: float) -> float:
        for name in (f"{base}_ram[{no}]", f"{base}[{no}]"):
            if unit.has(name) and unit.raw(name) != 0:
                return unit.number(name)
        return fallback

    # ---- hooks --------------------------------------------------------------------------
    def on_write(self, unit: Unit, name: str, raw: int) -> None:
        base, _, rest = name.partition("[")
        if base in _TWINS and rest and unit.has(f"{base}_ram[{rest}"):
            unit.set_raw(f"{base}_ram[{rest}", raw)
        if name == "alarm_reset" and raw == 1:
            self._reset_alarm(unit)
        elif name == "alarm_history_clear" and raw == 1:
            self._clear(unit, "alarm_history")
        elif name == "comm_error_history_clear" and raw == 1:
            self._clear(unit, "comm_error_history")
        self._update(unit, 0.0)

    def on_tick(self, unit: Unit, dt: float) -> None:
        self._watch_communication(unit, dt)
        self._update(unit, dt)

    def on_request(self, unit: Unit) -> None:
        unit.scratch["since_query"] = 0.0
        unit.scratch["timed_out"] = False

    def is_running(self, unit: Unit) -> bool:
        state = unit.raw("motor_state") if unit.has("motor_state") else STOP
        return state == RUN or float(unit.scratch.get("speed", 0.0)) > 0.0

    # ---- communication timeout (Tb1) --------------------------------------------------------
    def _watch_communication(self, unit: Unit, dt: float) -> None:
        since = unit.scratch.get("since_query")
        if since is None:  # no query yet: nothing to monitor
            return
        since = unit.scratch["since_query"] = since + dt
        name = "rs232_timeout" if unit.id == RS232_UNIT else "rs485_timeout"
        limit_ms = unit.get(name) if unit.has(name) else 0
        if not limit_ms or since * 1000.0 <= limit_ms or unit.scratch.get("timed_out"):
            return
        unit.scratch["timed_out"] = True
        code = unit.spec.protocol.comm_policy("timeout")
        if code is not None:
            unit.record_comm_error(code)
        action = unit.raw("comm_error_action") if unit.has("comm_error_action") else ACTION_ALARM
        if action in (ACTION_NET_IO_CLEAR, ACTION_BOTH) and unit.has("net_in"):
            unit.set_raw("net_in", 0)
        if action in (ACTION_ALARM, ACTION_BOTH):
            unit.scratch["comm_alarm"] = True
            if self.comm_timeout_alarm_no is not None and unit.has("alarm_no"):
                unit.set_raw("alarm_no", self.comm_timeout_alarm_no)

    # ---- state machine --------------------------------------------------------------------
    def _clear(self, unit: Unit, name: str) -> None:
        for i in range(_count(unit, name)):
            unit.set_raw(f"{name}[{i}]", 0)

    def _reset_alarm(self, unit: Unit) -> None:
        if unit.has("alarm_no"):
            unit.set_raw("alarm_no", 0)
        unit.scratch["alarm"] = 0
        unit.scratch["comm_alarm"] = False
        if unit.has("motor_state") and unit.raw("motor_state") == FAULT:
            unit.set_raw("motor_state", STOP)

    def _alarm(self, unit: Unit) -> int:
        code = unit.raw("alarm_no") if unit.has("alarm_no") else 0
        if code and unit.scratch.get("alarm", 0) != code and _count(unit, "alarm_history"):
            for i in range(_count(unit, "alarm_history") - 1, 0, -1):
                unit.set_raw(f"alarm_history[{i}]", unit.raw(f"alarm_history[{i - 1}]"))
            unit.set_raw("alarm_history[0]", code)
        unit.scratch["alarm"] = code
        return code

    def _update(self, unit: Unit, dt: float) -> None:
        if not unit.has("motor_state"):
            return
        on = self._functions(unit)
        before = unit.scratch.get("functions", set())
        unit.scratch["functions"] = on
        if ({F_ALM_RST, F_EBRAKE_ALM_RST} & on) - before:
            self._reset_alarm(unit)
        speed = float(unit.scratch.get("speed", 0.0))
        direction = unit.raw("motor_direction") if unit.has("motor_direction") else CW
        if self._alarm(unit) or unit.scratch.get("comm_alarm"):
            self._show(unit, FAULT, 0.0, direction, 0.0)
            return
        if F_FREE in on or F_EBRAKE in on or F_EBRAKE_ALM_RST in on:
            self._show(unit, FREE if F_FREE in on else EBRAKE, 0.0, direction, 0.0)
            return
        if self._cc_mode(unit):
            fwd, rev = F_START_STOP in on, F_CCW_CW in on
            run = fwd != rev
            wanted = CCW if rev else CW
        else:
            run = F_START_STOP in on
            wanted = CCW if F_CCW_CW in on else CW
        if F_STOP in on:
            run = False
        no = self._selected(unit, on)
        target = self._data(unit, "digital_speed", no, 0.0) if run else 0.0
        if run and speed > 0.0 and wanted != direction:
            target = 0.0  # decelerate before reversing
        if not run and F_STOP_MODE in on:
            speed = 0.0  # immediate stop
        if speed < target:
            rate = RAMP_SPAN_RPM / max(self._data(unit, "digital_accel_time", no, 1.0), 0.1)
            speed = min(target, speed + rate * dt)
        elif speed > target:
            rate = RAMP_SPAN_RPM / max(self._data(unit, "digital_decel_time", no, 1.0), 0.1)
            speed = max(target, speed - rate * dt)
        if speed == 0.0 and run:
            direction = wanted
        state = RUN if run or speed > 0.0 else STOP
        self._show(unit, state, speed, direction, target if run else 0.0)

    def _show(self, unit: Unit, state: int, speed: float, direction: int, command: float) -> None:
        """Write the monitors, only where the computed value changed (presets stay as set)."""
        unit.scratch["speed"] = speed
        shown = unit.scratch.setdefault("shown", {})
        for name, value in (
            ("motor_state", state),
            ("motor_speed", int(round(speed))),
            ("motor_direction", direction),
            ("command_speed", int(round(command))),
        ):
            if unit.has(name) and shown.get(name) != value:
                unit.set_raw(name, value)
                shown[name] = value
