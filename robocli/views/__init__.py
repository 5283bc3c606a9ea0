"""The data behind the CLI's live views, for a script or a notebook too: each device's
state as one line of text or as JSON-ready SI data, the streams a live view redraws from,
and keys read from a terminal. Nothing here prints: the commands render what it returns."""
