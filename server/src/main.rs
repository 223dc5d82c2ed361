//! The `rigcast` binary: parses the command line and runs the subcommand.
use clap::Parser;

#[tokio::main]
async fn main() -> std::process::ExitCode {
    let cli = rigcast_server::cli::Cli::parse();
    match cli.command_or_default().run().await {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rigcast: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
