"""The built-in Pioneer (ARCOS) simulator: the robot's physics (:mod:`.model`, in a
:mod:`robocli.sim.world`), the protocol state machine of one client (:mod:`.session`,
:mod:`.simext`) and the server that puts them on TCP and a pty (:mod:`.server`)."""
