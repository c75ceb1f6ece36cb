"""The session folder of a fast playback (`sources.FastPlayback`): what it reads, copied with the
recorder's writers (raw logs with the recorded stamps, live CSVs, session.json); given a
`LostWrites`, a write that fails (a full disk) is counted there and the copy goes on."""
from __future__ import annotations

from pathlib import Path

from leonav.hardware.jsonfile import write_json
from leonav.hardware.records import GnssTimeTag, ImuSample
from leonav.hardware.session_files import (GNSS_FIX_COLUMNS, IMU_COLUMNS, CsvSink, LostWrites, RawLog, RunningTimeMap,
                                    gnss_rows, imu_row, session_json)


class SessionCopy:
    """The recorder's files for a fast playback: raw logs with the recorded stamps, live CSVs, session.json."""

    def __init__(self, folder: Path, source_info: dict, lost: LostWrites | None = None) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.source_info = source_info
        self.lost = lost
        self.raw = {k: RawLog(self.folder, k, lost) for k in ("gnss", "imu")}
        self.tmap = RunningTimeMap()
        self.fix_csv = CsvSink(self.folder / "gnss_fix.csv", GNSS_FIX_COLUMNS, lost)
        self.imu_csv = CsvSink(self.folder / "imu.csv", IMU_COLUMNS, lost)

    def chunk(self, kind: str, data: bytes, t: float) -> None:
        self.raw[kind].write(data, t)

    def gnss(self, rec) -> None:
        if isinstance(rec, GnssTimeTag):
            self.tmap.add(rec)
        name, rows = gnss_rows(rec, self.tmap.utc)
        if name == "gnss_fix":
            for row in rows:
                self.fix_csv.write(row)

    def imu(self, s: ImuSample) -> None:
        self.imu_csv.write(imu_row(s, self.tmap.utc))

    def close(self, status: str, summaries: dict) -> dict:
        for sink in (*self.raw.values(), self.fix_csv, self.imu_csv):
            sink.close()
        src = self.source_info
        devices = [{"kind": k, "port": f"playback:{k}", "baud": b, "error": ""} | summaries.get(k, {})
                   for k, b in (("gnss", _baud(src, "gnss")), ("imu", _baud(src, "imu")))]
        info = session_json(status, src.get("start_utc", ""), src.get("t_mono_start_s", 0.0), devices, None,
                            (src.get("stop_utc", ""), src.get("t_mono_stop_s", 0.0), self.tmap.final()))
        info["played_back_from"] = src.get("_folder", "")
        if self.lost is None:
            write_json(self.folder / "session.json", info)
            return info
        info["lost_writes"] = self.lost.under(self.folder)
        try:                      # best-effort: a session.json that did not fit is reported by the run
            write_json(self.folder / "session.json", info)
        except OSError as exc:
            self.lost.add(self.folder / "session.json", exc)
        return info


def _baud(info: dict, kind: str) -> int | None:
    for d in info.get("devices", []):
        if d.get("kind") == kind and isinstance(d.get("baud"), int):
            return d["baud"]
    return None
