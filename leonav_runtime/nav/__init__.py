"""Live navigation (`leonav nav`): the replay's road into the filter, fed causally.

Every piece here is the streaming twin of a batch piece of `leonav_runtime/replay/`, fed
with what has arrived so far and nothing later:

  timemap.py      online monotonic -> UTC map from GNSS time tags (replay: timebase)
  imu_timing.py   online WitMotion sample times from arrival stamps (replay: regular_sample_times)
  gnss_stream.py  GNSS records -> complete fix epochs -> `inputs.FixTable` rows (replay: gnss_table)
  road.py         tables -> records through `leonav_runtime.inputs` (`assemble` to start, the
                  same record functions for every later increment)
  stepper.py      the generated C filter on each arriving batch, with a fixed-lag window in
                  which a late measurement is put in its place and the window re-run
  beacon_stream.py  the beacon pipeline on a growing capture, chunk by chunk
  push_stft.py    the batch STFT driven by pushed sample blocks (the same slices)
  navigator.py    the loop: events in, records to the filter, solutions out, faults
  sources.py      live devices (the recorder's device threads), paced pty playback, fast playback
  outputs.py, status.py   NMEA/MAVLink/JSON lines, trajectory files, the terminal status line
  session_copy.py the session folder a fast playback writes (the recorder's writers)
  out_lock.py     one writer per output folder (an exclusive flock on OUT/.leonav-nav.lock)
  run.py          one run of `leonav nav`: sources + navigator + signals -> exit code
"""
