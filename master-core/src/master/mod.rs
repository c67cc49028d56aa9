//! The master: bring-up of the segment, slave addressing, AL states, topology watch, events.
