//! The `repertoire` command line.

mod cli;

use anyhow::Result;
use clap::Parser;

fn main() -> Result<()> {
    restore_sigpipe();
    let args = cli::Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(if args.verbose { "debug" } else { "info" })),
        )
        .with_writer(std::io::stderr)
        .with_target(false)
        .init();
    cli::run(args)
}

/// Dies quietly on a closed pipe (`repertoire scene mjcf | head`) like other Unix tools, instead
/// of the panic Rust's ignored SIGPIPE turns every later `println!` into.
fn restore_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in main, before any thread exists; SIG_DFL is always valid.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
