"""View models: everything a template needs, computed in Python so templates stay logic-free.

One module per output kind (``client``, ``spec``, ``simulator``, ``docs``); each has a
``context(model, options)`` function that the exporter of that output calls.
"""
