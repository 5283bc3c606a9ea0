"""Every benchmark of robocli: statistics and reports (:mod:`.stats`), child processes, CPU
pinning and the C floor (:mod:`.harness`), and one module per device (:mod:`.pioneer`,
:mod:`.arm`, :mod:`.hub`)."""
