//! `rigcast token show|rotate [--token-file PATH] [--listen ADDR]`: print or replace the
//! control token that clients present to change the server (see [`crate::token`]).

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand};

use crate::config::DEFAULT_LISTEN;

/// Options of `rigcast token`.
#[derive(Debug, Args)]
pub struct TokenArgs {
    /// What to do.
    #[command(subcommand)]
    pub action: TokenAction,
    /// The token file (default `$XDG_CONFIG_HOME/rigcast/token`, else `~/.config/rigcast/token`).
    #[arg(long, global = true)]
    pub token_file: Option<PathBuf>,
    /// The server address used in the printed viewer link.
    #[arg(long, global = true, default_value = DEFAULT_LISTEN)]
    pub listen: String,
}

/// `rigcast token` actions.
#[derive(Debug, Clone, Copy, Subcommand)]
pub enum TokenAction {
    /// Print the token (creating it if there is none yet) and a viewer link carrying it.
    Show,
    /// Replace the token with a new random one; clients holding the old one lose control
    /// (a running server reads the file at start: restart it).
    Rotate,
}

/// Runs `rigcast token`.
pub fn run(args: &TokenArgs) -> anyhow::Result<()> {
    let path = match &args.token_file {
        Some(p) => p.clone(),
        None => crate::token::default_token_path()
            .context("no token file location: set XDG_CONFIG_HOME or HOME, or pass --token-file")?,
    };
    let token = match args.action {
        TokenAction::Show => crate::token::load_or_create(&path)?.0,
        TokenAction::Rotate => {
            let t = crate::token::rotate(&path)?;
            eprintln!(
                "rigcast: new control token written to {} (restart a running server to use it)",
                path.display()
            );
            t
        }
    };
    println!("{}", token.reveal());
    eprintln!(
        "  viewer with control: http://{}/?token={}",
        args.listen,
        token.reveal()
    );
    Ok(())
}
