//! Human motion import.
