//! The `rigcast` binary: parses the command line and runs the subcommand.
use clap::Parser;

#[tokio::main]
async fn main() -> std::process::ExitCode {
    // Library code logs through `tracing`; warnings and errors reach stderr by default,
    // `RIGCAST_LOG=debug` (or any `EnvFilter` directive) shows more.
    let filter = tracing_subscriber::EnvFilter::try_from_env("RIGCAST_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .without_time()
        .init();
    // A fault that repeats (a target retried every 250 ms) prints one report a minute, not four a second.
    rigcast_server::panic_reports::install();
    let command = rigcast_server::cli::Cli::parse().command_or_default();
    if command.is_offline() {
        end_quietly_when_stdout_closes();
    }
    match command.run().await {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rigcast: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// An offline subcommand whose reader stops early (`rigcast info walk.bvh | head`) ends quietly,
/// as any Unix tool does, instead of panicking in `println!` on the closed pipe: SIGPIPE gets
/// its default action back (Rust ignores it so that a write returns an error instead). Only
/// for commands without sockets, where a peer going away must stay an error to handle, never
/// the end of the process.
fn end_quietly_when_stdout_closes() {
    #[cfg(unix)]
    // SAFETY: `signal` with `SIG_DFL` installs no handler code; it only changes this process's
    // disposition of SIGPIPE, which nothing else in rigcast sets.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
