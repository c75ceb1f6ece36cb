"""Live navigation outputs: the solution record and its sinks (NMEA over TCP / pty,
MAVLink, JSON lines). Servers listen on 127.0.0.1 unless the user names another address."""
