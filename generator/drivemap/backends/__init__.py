"""The back ends: exporters (one plugin interface), their views and templates, and the file writer.
"""
