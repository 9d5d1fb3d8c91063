"""``drivemap gateway``: fleets of drives published to MQTT (with Home Assistant discovery) and OPC UA.

:mod:`.config` (the configuration and its checks), :mod:`.device` (values and checked commands),
:mod:`.lines` (one task per bus), :mod:`.mqtt`, :mod:`.discovery`, :mod:`.opcua` (optional extra
``drivemap[opcua]``), :mod:`.service` (the running gateway and the command line).
"""

from __future__ import annotations
