"""Device drivers: the rotary table (text protocol over pyserial) and the DAQ (Modbus TCP).

``drivers.base`` holds the ``RotaryTable`` and ``Daq`` protocols and ``drivers.errors`` the
``DriverError`` tree; ``drivers.sim`` simulates both devices and the sensor's physics.
Layer rule: the bottom layer; it imports nothing of ``bench``, ``db``, ``station`` or ``api``.
"""
