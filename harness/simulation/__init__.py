"""Simulation adapter over highway-env: scenario in, one :class:`~harness.world.state.WorldState` per frame out.

* :mod:`.road` — the straight multi-lane highway-env road network a scenario describes;
* :mod:`.placement` — where the ego, placed vehicles and random traffic start (pure geometry);
* :mod:`.vehicles` — the scenario's vehicles as highway-env vehicles (IDM/MOBIL, cruise, stationary);
* :mod:`.events` — timed events (brake, cut-in, speed change) as controllers handed to vehicles;
* :mod:`.simulator` — :class:`Simulation` / :func:`simulate`, stepping once per frame.
"""
