"""The vocabulary both sides of drivemap need, each fact once, below everyone who uses it:

* :mod:`.units`: units and device classes as Home Assistant and ESPHome name them, decimals of a scaled value
  (the homeassistant and esphome exporters, the gateway's discovery);
* :mod:`.csv_columns`: the columns of drivemap's register spreadsheet (the csv exporter, ``import csv``);
* the naming policy of generated outputs: :mod:`.reserved` (what the generated package and docs already
  use, as data), :mod:`.namecheck` (a map's names against it and each other), :mod:`.escape` (text as
  Python and Markdown hold it, heading anchors): the python and docs exporters check with it, draft and
  import name registers by it.

It imports the model and the runtime's name rules, nothing of the compiler, the back ends or the applications.
"""
