"""Every benchmark of robocli: shared statistics and child processes (:mod:`.common`), the
Pioneer (:mod:`.pioneer` once split), the arm (:mod:`.arm`) and the hub (:mod:`.hub`)."""
