"""The front end: a project's maps, loaded with line/column, validated by the schema and the semantic checks.

Imports the model and the diagnostics only; it knows no back end.
"""
