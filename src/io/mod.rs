//! Readers for the CSV inputs, with errors that name the file, the line and the field.
