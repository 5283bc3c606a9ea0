"""The hub's front-ends: each one serves the same sources and rings to one kind of client
(:mod:`.ros4mat`: the ros4mat v3 protocol over TCP; :mod:`.zenoh`: Eclipse Zenoh, with
:mod:`.ros2` beside it for ``--ros2``)."""
