"""errors.py - the daemon's error codes as exceptions: Rbx1Error (.code, .message) and one subclass per code."""


class Rbx1Error(Exception):
    """An error reply ({"error": {"code", "message"}}) or a client-side failure. Codes without a class of their own
    (a newer daemon's) come as this base class, with .code still set."""

    code = None

    def __init__(self, message, code=None, reply=None):
        self.code = code or type(self).code or "error"
        self.message = message
        self.reply = reply  # the whole final line (with the HTTP API: also "events"), when there was one
        super().__init__(f"{self.code}: {message}")


# ---- the request itself was wrong (the CLI exits 2; the console answers 400) ---------------------------------

class RequestError(Rbx1Error):
    """The request was malformed: the daemon never acted on it."""


class BadJson(RequestError):
    code = "bad_json"


class BadRequest(RequestError):
    code = "bad_request"


class UnknownCommand(RequestError):
    code = "unknown_command"


class MissingField(RequestError):
    code = "missing_field"


class BadField(RequestError):
    code = "bad_field"


class LineTooLong(RequestError):
    code = "line_too_long"


# ---- the arm could not do it (the CLI exits 1; the console answers 409) ---------------------------------------

class Busy(Rbx1Error):
    """A job is running (or too many control connections)."""
    code = "busy"


class NotReady(Rbx1Error):
    """Link down, firmware not homed or enabled, a reset firmware waiting for clear_fault."""
    code = "not_ready"


class Fault(Rbx1Error):
    """The firmware is in FAULT: clear_fault first."""
    code = "fault"


class Estop(Rbx1Error):
    """The job was stopped by an e-stop."""
    code = "estop"


class EstopActive(Rbx1Error):
    """clear_fault refused: the e-stop input is still held."""
    code = "estop_active"


class ObjectAbsent(Rbx1Error):
    """The requested object is not in the scene (the arm went home)."""
    code = "object_absent"


class UnknownPlace(Rbx1Error):
    code = "unknown_place"


class PlanFailed(Rbx1Error):
    code = "plan_failed"


class PickFailed(Rbx1Error):
    code = "pick_failed"


class PickUnverified(Rbx1Error):
    """A frame judging a pick (the pick check's, the sort's next scan) saw nothing at all, twice, where the scan
    before saw several objects (a blind frame)."""
    code = "pick_unverified"


class CameraFailed(Rbx1Error):
    code = "camera_failed"


class VisionFailed(Rbx1Error):
    code = "vision_failed"


class Rejected(Rbx1Error):
    """The firmware refused a step."""
    code = "rejected"


class Timeout(Rbx1Error):
    """The daemon's own time limit (a move, the job, a reconnection) ran out; see NoReply for the client's."""
    code = "timeout"


class LinkDown(Rbx1Error):
    code = "link_down"


class LinkError(Rbx1Error):
    code = "link_error"


class FirmwareReset(Rbx1Error):
    code = "firmware_reset"


class Stopped(Rbx1Error):
    """The firmware flushed the job's entries (a STOP from elsewhere)."""
    code = "stopped"


class Shutdown(Rbx1Error):
    """The job was aborted by the daemon's shutdown."""
    code = "shutdown"


class ShuttingDown(Rbx1Error):
    """The daemon is shutting down and takes no more jobs."""
    code = "shutting_down"


class Aborted(Rbx1Error):
    code = "aborted"


class ClientGone(Rbx1Error):
    """A jog whose client went away."""
    code = "client_gone"


class Internal(Rbx1Error):
    code = "internal"


# ---- the operator's commands -----------------------------------------------------------------------------------

class JogTooFar(Rbx1Error):
    """Above [operator] jog_max_deg / jog_max_mm."""
    code = "jog_too_far"


class OutOfLimits(Rbx1Error):
    code = "out_of_limits"


class BadPose(Rbx1Error):
    code = "bad_pose"


class StateFailed(Rbx1Error):
    """A state file (poses, places, background, library, workspace) could not be written."""
    code = "state_failed"


class NoObject(Rbx1Error):
    """teach: no object of that index in the live scan."""
    code = "no_object"


class Uncalibrated(Rbx1Error):
    """The command needs a calibration in force."""
    code = "uncalibrated"


class NoCalibration(Rbx1Error):
    """calibrate_workspace: no session in progress."""
    code = "no_calibration"


class UnknownMarker(Rbx1Error):
    code = "unknown_marker"


class NotOnTable(Rbx1Error):
    code = "not_on_table"


class TooFewMarkers(Rbx1Error):
    code = "too_few_markers"


class DuplicateMarker(Rbx1Error):
    code = "duplicate_marker"


class Degenerate(Rbx1Error):
    """The recorded markers do not span the table (collinear, coincident)."""
    code = "degenerate"


class FitRejected(Rbx1Error):
    code = "fit_rejected"


# ---- the web console's HTTP API --------------------------------------------------------------------------------

class Unauthorized(Rbx1Error):
    """A missing or wrong console token."""
    code = "unauthorized"


class BadOrigin(Rbx1Error):
    code = "bad_origin"


class NotAllowed(Rbx1Error):
    """Not available through the console (shutdown)."""
    code = "not_allowed"


class NotFound(Rbx1Error):
    code = "not_found"


class NoScan(Rbx1Error):
    code = "no_scan"


class TooManyStreams(Rbx1Error):
    code = "too_many_streams"


# ---- the cell's jobs (sort, clear, recipes, history) ---------------------------------------------------------

class BadRecipe(Rbx1Error):
    """The recipe names a place or a class the arm does not know."""
    code = "bad_recipe"


class UnknownRecipe(Rbx1Error):
    code = "unknown_recipe"


class NoJob(Rbx1Error):
    """pause, resume or cancel with no sort or clear running."""
    code = "no_job"


class Cancelled(Rbx1Error):
    code = "cancelled"


class HistoryFailed(Rbx1Error):
    code = "history_failed"


class NoImage(Rbx1Error):
    code = "no_image"


class TooLarge(RequestError):
    """A command over MQTT larger than the interface takes."""
    code = "too_large"


class Stale(RequestError):
    """A command over MQTT that was retained, older than [mqtt] max_age_s, or undated just after a reconnect."""
    code = "stale"


# ---- the client's own ------------------------------------------------------------------------------------------

class NoReply(Rbx1Error, TimeoutError):
    """No reply line within the client's timeout (the request may still be running in the daemon)."""
    code = "no_reply"


class Disconnected(Rbx1Error, ConnectionError):
    """Could not connect, or the connection closed before the final line (the daemon stopped or dropped us)."""
    code = "disconnected"


def _codes(base):
    out = {}
    for cls in base.__subclasses__():
        if cls.code:
            out[cls.code] = cls
        out.update(_codes(cls))
    return out


# Every code with a class of its own.
CODES = _codes(Rbx1Error)


def error_from(final):
    """The exception for a final line {"error": {"code", "message"}}: its code's class, else Rbx1Error."""
    e = final.get("error") or {}
    code = e.get("code") or "error"
    return CODES.get(code, Rbx1Error)(e.get("message", ""), code=code, reply=final)
