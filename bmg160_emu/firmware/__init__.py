"""The ATmega328P firmware front end: header generation, build driver, simulated chip.

The firmware itself (C, avr-libc) is in the repository's ``firmware/`` folder; see
docs/firmware.md.
"""
