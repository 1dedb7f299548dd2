//! `sdctl`: the toolkit's capabilities on files (formats in docs/formats.md).
//!
//! Exit status: 0 success; 2 bad input or usage (one line on stderr saying what and where);
//! 1 a numerical failure that is not the input's fault. Outputs are written atomically
//! (temporary file + rename), so a failed run never leaves a half-written file.

mod cmd;
mod commands;
mod io;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    // A panic is a bug: report it on one line, never with a trace.
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown".into());
        // `println!` to a reader that has gone (`sdctl … | head`) is no error of ours
        if msg.starts_with("failed printing to stdout") && msg.contains("Broken pipe") {
            std::process::exit(0);
        }
        eprintln!("sdctl: internal error (please report): {msg}");
    }));
    let cli = match commands::Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(
                e.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) {
                let _ = e.print();
                return if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                    ExitCode::from(2)
                } else {
                    ExitCode::SUCCESS
                };
            }
            let text = e.to_string();
            // clap's message up to its usage block, folded onto one line
            let msg: Vec<&str> = text
                .lines()
                .take_while(|l| !l.trim().is_empty() && !l.starts_with("Usage:"))
                .map(|l| l.trim().trim_start_matches("error: "))
                .collect();
            eprintln!("sdctl: {} (see sdctl --help)", msg.join(" "));
            return ExitCode::from(2);
        }
    };
    match std::panic::catch_unwind(|| commands::run(cli)) {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(e)) => {
            eprintln!("sdctl: {}", e.message);
            ExitCode::from(e.code)
        }
        Err(_) => ExitCode::from(1),
    }
}
