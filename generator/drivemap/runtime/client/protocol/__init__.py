"""Protocol: what a client asks of a device, written once as generators (the sans-I/O
:class:`~drivemap.runtime.client.protocol.sansio.Core`): read plans, the requests and checks of every
operation, page visits, reviews, the compiled read and write programs, and how an operation runs on a
bus (sync or async, :mod:`.runner`). Uses the values and the transport, never the API above it."""
