"""pycreate2's drive-and-read, as its README shows it, unmodified: run by
tests/sim/test_create_sim.py as ``python pycreate2_drive.py PORT`` (PORT: the serial port
string; a pty, or a robocli URL). It drives forward, turns left in place, stops, reading
group 100 all along, and prints the sums of the distance (mm) and angle (deg) packets as
JSON on its last line. Loops end on what the robot reports (bounded by a deadline), not on
sleeps. pycreate2's own clean-up (``__del__``: stop, LEDs off, OI off) runs at exit."""

import json
import sys
import time

from pycreate2 import Create2

DEADLINE_S = 60.0


def main(port):
    bot = Create2(port)
    bot.start()
    bot.safe()
    total = {"distance": 0, "angle": 0, "reads": 0, "modes": []}

    def read():
        s = bot.get_sensors()
        total["distance"] += s.distance
        total["angle"] += s.angle
        total["reads"] += 1
        if s.open_interface_mode not in total["modes"]:
            total["modes"].append(s.open_interface_mode)
        return s

    end = time.monotonic() + DEADLINE_S
    bot.drive_direct(200, 200)  # right, left mm/s
    while total["distance"] < 300 and time.monotonic() < end:
        read()
    bot.drive_direct(100, -100)  # turn left in place
    while total["angle"] < 90 and time.monotonic() < end:
        read()
    bot.drive_stop()
    while time.monotonic() < end:  # until the robot reports it moved no more
        s = read()
        if s.distance == 0 and s.angle == 0 and s.velocity_left == 0:
            break
    s = read()
    total["voltage"], total["charge"] = s.voltage, s.battery_charge
    print(json.dumps(total), flush=True)


if __name__ == "__main__":
    main(sys.argv[1])
