"""Demonstration datasets: episodes played by a controller, recorded step by step and stored
in the Farama Minari format (``pianist dataset build``, docs/datasets.md).

:mod:`pianist.data.record` records one episode (:func:`record_episode`, the unit a sweep can
run), :mod:`pianist.data.minari_io` writes and reads the Minari dataset, and
:mod:`pianist.data.build` runs the grid of songs x episodes with resume and local workers.
Minari (the ``data`` extra) is imported only inside the functions that need it.
"""
