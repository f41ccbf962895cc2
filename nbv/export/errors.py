"""The one error of an export."""


class ExportError(ValueError):
    """A source or destination that cannot be exported to; the message names the file."""
