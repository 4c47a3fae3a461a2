//! Attitude from known directions.
