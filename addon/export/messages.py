"""What an export tells the user: the notes it collects and the error that stops it."""


class ExportError(Exception):
    """A scene that cannot be rendered; the message is meant for the user."""


class Messages:
    """What the exporter approximated or ignored: each message once, in order."""

    def __init__(self):
        self._seen = set()
        self.items = []

    def add(self, text):
        if text not in self._seen:
            self._seen.add(text)
            self.items.append(text)
