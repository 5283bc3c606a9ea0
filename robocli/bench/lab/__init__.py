"""A lab of robots and laptops on one machine, in network namespaces (:mod:`.netns`), and
the bench that runs the hub's front-ends over it (:mod:`.bench`)."""
