use anyhow::Context;
use atlastree::paging::serve;
use atlastree::util::human_bytes;
use clap::Args;
use std::io::Write;
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// `10s`, `500ms`, `2` (seconds): a positive, finite duration.
fn parse_duration(s: &str) -> Result<Duration, String> {
    let Some(v) = atlastree::util::parse_seconds(s) else {
        return Err(format!("{s} is not a duration: expected e.g. 10s or 500ms"));
    };
    if v.is_nan() || v <= 0.0 {
        return Err(format!("{s}: a timeout must be longer than 0 (e.g. 10s)"));
    }
    if !v.is_finite() || v >= 1e9 {
        return Err(format!(
            "{s}: at most 1e9 s (about 32 years); a connection is never meant to wait that long"
        ));
    }
    Ok(Duration::from_secs_f64(v))
}

// The command's help text is the doc comment of `Command::Serve` (src/cli/mod.rs).
#[derive(Args, Debug)]
pub(crate) struct ServeArgs {
    /// A paging file written by `atlastree build`.
    pub file: PathBuf,
    /// TCP port; 0 picks a free one (printed).
    #[arg(long, default_value_t = 8077, allow_hyphen_values = true)]
    pub port: u16,
    /// Address to listen on. The default serves this machine only; `0.0.0.0` serves the network.
    #[arg(long, default_value = "127.0.0.1")]
    pub bind: IpAddr,
    /// Connections served at once; one more waits up to 2 s for a free slot, then gets 503.
    #[arg(long, default_value_t = 256,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=1 << 20))]
    pub max_connections: usize,
    /// A request head must arrive within this time (slow clients are closed; also the keep-alive idle
    /// limit), e.g. `10s`, `500ms`.
    #[arg(long, default_value = "10s", value_parser = parse_duration)]
    pub header_timeout: Duration,
    /// A connection that moves no byte either way this long is closed, e.g. `30s`.
    #[arg(long, default_value = "30s", value_parser = parse_duration)]
    pub io_timeout: Duration,
    /// Print one JSON line `{"url", "addr", "blocks", "file_bytes"}` instead of text (for scripts: read
    /// the first line of stdout to get the URL).
    #[arg(long)]
    pub json: bool,
}

pub(super) fn run(a: ServeArgs) -> anyhow::Result<ExitCode> {
    for (flag, t) in [
        ("--header-timeout", a.header_timeout),
        ("--io-timeout", a.io_timeout),
    ] {
        if t < Duration::from_millis(1) {
            anyhow::bail!("{flag} {t:?} is below 1ms: every transfer would be cut short");
        }
    }
    let checked =
        (std::fs::metadata(&a.file).ok()).and_then(|m| atlastree::util::file_identity(&m));
    let file = super::open_local(&a.file, "serve", atlastree::store::LoadMode::Auto)?;
    let (blocks, file_bytes) = (file.blocks().len(), file.file_len());
    drop(file);
    let options = serve::ServeOptions {
        max_connections: a.max_connections,
        header_timeout: a.header_timeout,
        io_timeout: a.io_timeout,
        ..serve::ServeOptions::default()
    };
    // Installed before the server starts and its URL is printed: a Ctrl-C as soon as the URL shows stops
    // the server (tokio installs its handler when the signal is first awaited: one SIGINT in 20 right
    // after the URL killed the process), and a handler that cannot start (out of file descriptors) is an
    // error before anything is announced.
    let (signals, interrupted) = interrupt_handler()?;
    let server = serve::spawn_with(&a.file, SocketAddr::new(a.bind, a.port), options)?;
    // The server opens the path again; a file renamed over it in between (a build publishing) would be
    // served unchecked, under the checked file's URL, blocks and size (fault hunt, session 32).
    if checked.is_some() && server.file_identity() != checked {
        drop(server);
        anyhow::bail!(
            "{}: the file was replaced while serve checked it (a build publishing it?): run serve again",
            a.file.display()
        );
    }
    if a.json {
        let line = serde_json::json!({
            "url": server.url(),
            "addr": server.addr().to_string(),
            "blocks": blocks,
            "file_bytes": file_bytes,
        });
        println!("{line}");
    } else {
        println!(
            "serving {} ({blocks} blocks, {}) at {}",
            a.file.display(),
            human_bytes(file_bytes),
            server.url()
        );
        println!("press Ctrl-C to stop");
    }
    std::io::stdout().flush()?;
    signals.block_on(interrupted)?;
    server.shutdown();
    if !a.json {
        println!("stopped");
    }
    Ok(ExitCode::SUCCESS)
}

/// A runtime with the SIGINT (Ctrl-C) handler installed now (Unix), and the future that resolves on the
/// first SIGINT. Elsewhere the future is tokio's `ctrl_c`, whose handler is installed when first awaited.
fn interrupt_handler() -> anyhow::Result<(
    tokio::runtime::Runtime,
    impl std::future::Future<Output = anyhow::Result<()>>,
)> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .build()
        .context("starting the signal handler")?;
    #[cfg(unix)]
    let waiting = {
        use tokio::signal::unix::{SignalKind, signal};
        let mut interrupt = runtime
            .block_on(async { signal(SignalKind::interrupt()) })
            .context("starting the signal handler")?;
        async move {
            interrupt.recv().await;
            Ok(())
        }
    };
    #[cfg(not(unix))]
    let waiting = async { tokio::signal::ctrl_c().await.context("waiting for Ctrl-C") };
    Ok((runtime, waiting))
}

#[cfg(test)]
mod tests {
    #[test]
    fn durations_say_what_is_wrong() {
        use super::parse_duration;
        assert_eq!(parse_duration("500ms").unwrap().as_millis(), 500);
        assert!(parse_duration("x").unwrap_err().contains("not a duration"));
        assert!(parse_duration("0s").unwrap_err().contains("longer than 0"));
        assert!(
            parse_duration("99999999999s")
                .unwrap_err()
                .contains("at most 1e9 s")
        );
    }
}
