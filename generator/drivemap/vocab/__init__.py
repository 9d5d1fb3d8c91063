"""The vocabulary both sides of drivemap need, each fact once, below everyone who uses it: units and
device classes as Home Assistant and ESPHome name them (:mod:`.units`), the columns of drivemap's
register spreadsheet (:mod:`.csv_columns`). The exporters, the gateway and the importers read it;
it imports nothing of drivemap."""
