"""What an FMU logs, bounded: the last KEEP messages in memory (for the error message of a call that
fails) and, once the run names one, a log file capped in messages and bytes. A chatty FMU costs a
fixed amount of memory however long the run."""
from collections import deque

KEEP = 20                      # messages kept in memory per FMU
MESSAGE_CHARS = 2000           # a longer message is cut (in memory and in the file)
FILE_MESSAGES = 100_000        # messages written to the log file at most (all FMUs of a run together)
FILE_BYTES = 20 << 20          # bytes written to the log file at most
STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}


def cut(text, limit=MESSAGE_CHARS):
    """text, cut to `limit` characters with a note of how long it was."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


class LogFile:
    """One run's FMU log file, opened at its first message, capped; shared by the run's FMUs."""

    def __init__(self, path):
        self.path, self.file, self.error = path, None, None
        self.messages = self.bytes = self.dropped = 0

    def write(self, name, status, text):
        """One message (called from an FMU's logger callback: it never raises; a file that cannot be
        written takes no more messages)."""
        if self.messages >= FILE_MESSAGES or self.bytes >= FILE_BYTES or self.error is not None:
            self.dropped += 1
            return
        line = f"{name}: {STATUS.get(status, status)}: {text}\n".encode("utf-8", "replace")
        try:
            if self.file is None:
                self.file = open(self.path, "wb")
            self.file.write(line)
        except OSError as exc:
            self.error = exc
            return
        self.messages, self.bytes = self.messages + 1, self.bytes + len(line)

    def close(self):
        """Flush and close, noting the messages the caps left out; raises the OSError that stopped it."""
        if self.file is not None:
            file, self.file = self.file, None
            with file:
                if self.dropped and self.error is None:
                    file.write(f"... {self.dropped} further messages not written (the log keeps {FILE_MESSAGES} "
                               f"messages and {FILE_BYTES >> 20} MB)\n".encode())
        if self.error is not None:
            raise self.error


class MessageLog:
    """The messages of one FMU: the last KEEP in memory, all (up to the caps) in a LogFile once attached."""

    def __init__(self, name):
        self.name, self.recent, self.count, self.file = name, deque(maxlen=KEEP), 0, None

    def append(self, entry):
        """(status, text) from the FMU's logger callback."""
        status, text = entry
        text = cut(text)
        self.recent.append((status, text))
        self.count += 1
        if self.file is not None:
            self.file.write(self.name, status, text)

    def attach(self, log_file):
        """From now on also into log_file (the messages kept so far go there first)."""
        self.file = log_file
        for status, text in self.recent:
            log_file.write(self.name, status, text)

    def last(self):
        return self.recent[-1][1] if self.recent else None

    def __len__(self):
        return self.count

    def __iter__(self):
        return iter(self.recent)

    def __getitem__(self, k):
        return list(self.recent)[k]
