//! The `vgps` command-line tool: a thin binary over the library.
fn main() -> std::process::ExitCode {
    vgps::cli::main()
}
