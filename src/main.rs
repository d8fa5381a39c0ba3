//! `atlastree`: the command-line front end. clap arguments → validated options → library call → report.

#![warn(unreachable_pub)]

mod cli;

fn main() -> std::process::ExitCode {
    quiet_on_closed_stdout();
    cli::init_tracing();
    match cli::run() {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            std::process::ExitCode::from(2)
        }
    }
}

/// A report piped into `head` (stdout closed early) ends the process quietly with the shell's status
/// for SIGPIPE (141), as other command-line tools do, instead of a panic from `println!`; a panic in
/// winit is left to `view`'s error; every other panic keeps the default report.
fn quiet_on_closed_stdout() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let text = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if text.starts_with("failed printing to stdout") && text.contains("Broken pipe") {
            std::process::exit(141);
        }
        // winit unwraps its connection's errors (an X server gone under `view`); `view` catches the
        // panic and ends with an error naming it, so its report is not printed twice.
        if info
            .location()
            .is_some_and(|l| l.file().contains("/winit-"))
        {
            return;
        }
        default(info);
    }));
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
