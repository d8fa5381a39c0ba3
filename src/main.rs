//! `atlastree`: the command-line front end. clap arguments → validated options → library call → report.

#![warn(unreachable_pub)]

mod cli;

fn main() -> std::process::ExitCode {
    cli::init_tracing();
    match cli::run() {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            std::process::ExitCode::from(2)
        }
    }
}

/// The error and its causes joined by `: `, leaving out a cause whose text the message already holds (many
/// library errors print their source in their own message, as `thiserror`'s `{source}` does) and a file
/// name the message already ends with.
fn error_chain(e: &anyhow::Error) -> String {
    let mut message = e.to_string();
    for cause in e.chain().skip(1) {
        let text = cause.to_string();
        if message.contains(&text) {
            continue;
        }
        // "opening F" + "F: reason" → "opening F: reason" (the file named once).
        let rest = match text.split_once(": ") {
            Some((head, rest)) if message.ends_with(head) => rest,
            _ => &text,
        };
        message.push_str(": ");
        message.push_str(rest);
    }
    message
}
