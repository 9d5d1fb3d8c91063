"""Transport: one pymodbus client per line and what it carries out (exchanges), with the line's
timing, stale-reply guard, serial receive and the reply quirks a map allows. Knows nothing of maps'
registers, plans or values."""
