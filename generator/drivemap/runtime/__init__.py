"""The hand-written runtime that generated clients and simulators call.

Protocol behaviour lives here once: framing (through pymodbus), read planning, scaling and
range checks, retries and timing, exceptions, the simulator core.
"""
