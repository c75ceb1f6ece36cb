"""`leonav base`: a receiver at a known position serving differential corrections (docs/corrections.md).

protocol.py   the line protocol (HDR / COR / HB lines, `*hh` checksums) and its parser
compute.py    corrections = measured - predicted at the known position, smoothed per satellite
server.py     the TCP server (127.0.0.1 by default) that sends them to every connected rover
client.py     the rover's reader: connects, reconnects, parses and counts, fills the road's
              `inputs.corrections.DifferentialCorrections`
simulated.py  a simulated base/rover pair sharing one ephemeris error draw
"""
