//! `atlastree`: the command-line front end. clap arguments → validated options → library call → report.

#![warn(unreachable_pub)]

mod cli;

fn main() -> std::process::ExitCode {
    cli::init_tracing();
    match cli::run() {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::from(2)
        }
    }
}
