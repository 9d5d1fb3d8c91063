"""``drivemap import FORMAT FILE...``: register definitions users already own (Home Assistant, ESPHome,
SunSpec models, CSV) as maps that validate as written; what a source does not state stays out."""
