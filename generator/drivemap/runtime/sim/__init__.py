"""The simulator: a pymodbus server that answers like the device, its state file, CLI and behaviours.
"""
