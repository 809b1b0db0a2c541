"""JT/T 808 (editions 2013 and 2019): the terminal protocol of commercial vehicles in China.

Terminals of trucks, coaches and dangerous-goods vehicles send binary frames over TCP to their
fleet platform: location reports (``0x0200``, batches ``0x0704``) answered by the platform's
general response (``0x8001``); the platform speaks to the driver with text and text-to-speech
(``0x8300``). :mod:`.frames` delimits, escapes, checks and heads the frames; :mod:`.messages`
reads and writes the bodies this gateway uses.
"""
