//! `atlastree`: the command-line front end. clap arguments → validated options → library call → report.

#![warn(unreachable_pub)]

mod cli;

fn main() -> std::process::ExitCode {
    quiet_on_closed_stdout();
    cli::init_tracing();
    match cli::run() {
        Ok(code) => code,
        Err(e) => {
            // A temp a failing command could not remove while it held its files open (an export out of
            // descriptors) is removed now that they are closed; every other guard is gone already.
            atlastree::util::remove_live_temps();
            // Not `eprintln!`: a stderr whose reader has gone must not turn the error into a panic.
            use std::io::Write;
            let _ = writeln!(std::io::stderr(), "error: {}", error_chain(&e));
            std::process::ExitCode::from(2)
        }
    }
}

/// A report piped into `head` (stdout closed early), or a warning written to a stderr whose reader has
/// gone, ends the process quietly with the shell's status for SIGPIPE (141), as other command-line
/// tools do, instead of a panic from `println!`/`eprintln!` (a closed stderr's panic exited 101;
/// fault hunt, session 37), removing first what an interrupt removes (temps, the folders a run made
/// for its outputs); a panic in winit while a `view` session runs is left to its error; every other
/// panic keeps the default report.
fn quiet_on_closed_stdout() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let text = atlastree::util::panic_message(info.payload());
        let closed = |stream: &str| text.starts_with(&format!("failed printing to {stream}"));
        if (closed("stdout") || closed("stderr")) && text.contains("Broken pipe") {
            // Removed and ended under the temps' lock, as an interrupt does: no temp made in between.
            atlastree::util::remove_live_temps_and_exit(|| std::process::exit(141), |_, _| {});
        }
        // Stdout on a full disk or a failing device (`inspect --json > f.json`, `>/dev/full`): an error
        // naming stdout and why, exit 2 as other errors (1 is `inspect --verify`'s violation), not a
        // panic's backtrace (fault hunt, session 38). A failing stderr has nowhere to say so: exit 2 alone.
        if closed("stdout") || closed("stderr") {
            use std::io::Write;
            let why = text.split_once(": ").map_or(text.as_str(), |(_, why)| why);
            let say = |_: usize, _: Option<&(usize, std::path::PathBuf)>| {
                if closed("stdout") {
                    let _ = writeln!(std::io::stderr(), "error: writing to stdout: {why}");
                }
            };
            atlastree::util::remove_live_temps_and_exit(|| std::process::exit(2), say);
        }
        // winit unwraps its connection's errors (an X server gone under `view`); while a session runs,
        // `view` catches such a panic and ends with an error naming it, so it is not printed twice.
        if info
            .location()
            .is_some_and(|l| atlastree::view::window_panic_caught(l.file()))
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
