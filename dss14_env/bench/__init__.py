"""``dss14 bench``: the runner that scores every controller the same way, and the benchmark."""
