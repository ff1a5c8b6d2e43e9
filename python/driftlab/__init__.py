"""driftlab from Python: logs as NumPy arrays, and the diagnose, eval and import commands in-process.

    import driftlab
    log = driftlab.open("run.mcap")          # anything the CLI reads: LCM logs, ROS 1/2 bags, MCAP, ULog, CARMEN
    odom = log.read("/odom")                 # {"stamp": int64 [us], "arrival": int64 [us], "pose.position.x": ...}
    d = driftlab.diagnose("run.mcap")        # the dict `driftlab diagnose --json` prints
    e = driftlab.eval(gt="gt.tum", est="run.lcm:POSE", align="se3")   # `driftlab eval ... --json`

Times are the log's: whole microseconds in int64 (TIME_UNIT), as LCM logs keep them. Errors are driftlab.Error (a
RuntimeError and a ValueError) with the command's one-line message. The C++ work runs without the GIL.
"""

import json as _json
import os as _os

from ._driftlab import Error
from ._driftlab import Log as _Log
from ._driftlab import diagnose_json as _diagnose_json
from ._driftlab import import_log as _import_log
from ._driftlab import run_command as _run_command

__all__ = ["Error", "Log", "TIME_UNIT", "open", "diagnose", "eval", "import_"]

TIME_UNIT = "us"
"""The unit of every time driftlab gives (stamps, arrivals): microseconds, int64, as LCM logs keep them."""


def _inputs(path):
    if isinstance(path, (list, tuple)):
        return [_os.fspath(p) for p in path]
    return [_os.fspath(path)]


class Log:
    """An opened log (open()). Another tool's recording is read through its cached conversion to an LCM log,
    made beside it once, as the CLI does.

    Attributes: path (as given), lcm_path (the LCM log read), channels (names, sorted), time_unit ("us").

    A read is a pass over the LCM log (read_all: a pass per core, each decoding its share of the channels). A
    damaged log (bytes between events) is mapped by the first read, which notes where each channel's events are,
    and the mapping is kept while the Log lives, so that later reads visit only their channels' events.
    """

    time_unit = TIME_UNIT

    def __init__(self, path):
        self._log = _Log(_inputs(path))

    @property
    def path(self):
        return self._log.path

    @property
    def lcm_path(self):
        return self._log.lcm_path

    @property
    def channels(self):
        """The channel names, sorted."""
        return self._log.channels

    def info(self):
        """Per channel: {"type": "driftlab.odometry_t" (None when unknown), "count", "bytes", "first_arrival",
        "last_arrival" [us]}, from the log's index (no message is decoded)."""
        return self._log.info()

    def read(self, channel):
        """Every message of channel (a list of channels: read_all(channel)) as a dict of NumPy arrays, one entry per message along the first axis:

        - one array per field, nested fields by dotted names ("pose.position.x"); a fixed-size array field as a 2-D
          array (messages x elements; more dimensions for a matrix), and a variable-length one too when every
          message holds as many elements, else an object array of 1-D arrays; strings as an object array of str;
        - "stamp": the header's stamp (header.utime), int64 [us] in the source's clock (None for a message
          without a header);
        - "arrival": the log's receive time of each message, int64 [us].

        Numbers keep their type (float64, float32, int64, ..., uint8 for bytes, bool). Messages of another type than
        the channel's first, or cut short, are left out. Raises KeyError for an unknown channel, driftlab.Error
        for a channel of no driftlab type.
        """
        if isinstance(channel, (list, tuple)):
            return self._log.read_many(list(channel))
        return self._log.read(channel)

    def read_all(self, channels=None):
        """Several channels at once: {channel: read(channel)}, for the given channel names, or by
        default for every channel of a driftlab type (the others are left out). Raises as read()."""
        return self._log.read_many(None if channels is None else list(channels))

    def __repr__(self):
        return "driftlab.Log(%r: %d channels)" % (self.path, len(self.channels))


def open(path):  # noqa: A001 (driftlab.open, as the issue names it)
    """Opens a log: an LCM log or another tool's recording (a ROS 1 or ROS 2 bag or bag folder, an MCAP file,
    a PX4 ULog, a CARMEN log; a list of the files of a split recording). Raises driftlab.Error with the CLI's
    message when it is none of them or holds no event."""
    return Log(path)


def diagnose(path, max_lag=0.3, window=10.0, channels=""):
    """`driftlab diagnose PATH --json` in-process: the diagnosis as the dict the command prints (times in
    seconds unless a key says utime [us]). max_lag: the skew search range [s] (--max-lag); window: the skew window
    [s] (--window); channels: only the channels fully matching this regex (-c)."""
    return _json.loads(_diagnose_json(_inputs(path), float(max_lag), float(window), str(channels)))


def _option_args(kwargs):
    args = []
    for key, value in kwargs.items():
        if value is None or value is False:
            continue
        option = "--" + key.replace("_", "-")
        if value is True:
            args.append(option)
        elif isinstance(value, (list, tuple)):
            args += [option, ",".join(repr(v) if isinstance(v, float) else str(v) for v in value)]
        elif isinstance(value, float):
            args += [option, repr(value)]
        else:
            args += [option, _os.fspath(value) if hasattr(value, "__fspath__") else str(value)]
    return args


def eval(gt=None, est=None, **options):  # noqa: A001 (driftlab.eval, as the command)
    """`driftlab eval --gt GT --est EST --json` in-process: the trajectory error as the dict the command prints.

    gt, est: LOG:CHANNEL or a TUM, KITTI or EuRoC file. Every other option of the command as a keyword, '-' as
    '_': align="se3", max_dt=0.02, offset="auto", interpolate=True, delta=1, delta_unit="m", all_pairs=True,
    segments=[10, 20], relations="rel.txt", relations_odometry=..., arm="arm.lcm", ... (True: a flag).
    """
    if "json" in options:
        raise TypeError("eval() returns the JSON: no json option")
    args = ["eval"]
    if gt is not None:
        args += ["--gt", _os.fspath(gt)]
    if est is not None:
        args += ["--est", _os.fspath(est)]
    args += _option_args(options) + ["--json"]
    return _json.loads(_run_command(args))


def import_(path, out):
    """`driftlab import PATH -o OUT` in-process: another tool's recording converted into the LCM log out. Returns
    {"format", "messages", "topics": [{"channel", "source_type", "driftlab_type", "messages", "malformed"}],
    "skipped", "problems": [one line each], "out"}. MRPT rawlogs need the CLI (driftlab import rawlog)."""
    return _import_log(_inputs(path), _os.fspath(out))
