"""Library errors. The CLI turns each into one line on stderr; nothing here prints."""


class LtcError(Exception):
    """Base of every error ltc raises on purpose.

    ``path`` names the file the problem is in, when there is one, so that the message the user sees
    always says where to look.
    """

    def __init__(self, message: str, path=None):
        super().__init__(message)
        self.message = message
        self.path = None if path is None else str(path)

    def __str__(self) -> str:
        return f"{self.path}: {self.message}" if self.path else self.message


class ConfigError(LtcError):
    """A bad configuration file or ``--set`` value."""


class RecordingError(LtcError):
    """A recording that cannot be read at all (bad recording.yaml, missing poses, ...)."""


class FrameError(LtcError):
    """One frame that cannot be used (missing image, wrong depth size, bad pose). Skippable."""


class MapFormatError(LtcError):
    """A file that is not an ltc map, or of a newer format version."""


class MapWriteError(LtcError):
    """A map that cannot be committed (read-only, folder not writable, disk full); the old map is
    unchanged."""


class MapLockedError(LtcError):
    """Another process is writing the map."""


class PluginError(LtcError):
    """An unknown plugin name, or a plugin that misbehaves."""


class SchemaError(LtcError):
    """A JSON / YAML document that does not follow its schema."""
