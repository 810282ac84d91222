"""Execution of a procedure on the bench: the run loop and its parts.

* ``loop``: :class:`Sequencer`, the run's loop: DAQ pumping, observers, blocking table calls
  under a deadline, the life cycle;
* ``outcome``: how the run ended (ABORTED, ERROR, resumable) and what it leaves behind;
* ``observers``: the run's observers told as one, an observer's failure named;
* ``progress``: the progress event and its expected duration;
* ``steps``: what each procedure step does on the table;
* ``window``: a static or motion window being recorded;
* ``daq``: the DAQ reader thread and what it hands over (blocks, gaps, restarts);
* ``control``: operator requests (abort, pause, resume) and the run's configuration;
* ``safety``: the table made ready before a run and safe after it.

Device access goes only through the ``drivers.base`` protocols.
"""
