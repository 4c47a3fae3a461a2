//! Inputs that made a fuzz target fail (see `docs/fuzzing.md`), replayed through the same
//! code path (`vgps::fuzzing::<target>`) and checked directly on the library function.
