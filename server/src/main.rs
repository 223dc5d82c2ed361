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
    let cli = rigcast_server::cli::Cli::parse();
    match cli.command_or_default().run().await {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rigcast: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
