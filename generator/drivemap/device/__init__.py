"""What every verb at a device shares, below the applications that talk to one (``live``: read, write,
watch, scan, verify; ``onboard``: probe; import's located argument errors): the map a device is read
with (:mod:`.target`), how it is reached (:mod:`.connection`: the connection options, the link, the
bus) and the verbs' exit codes and errors (:mod:`.errors`). It imports no application and no back end.
"""
