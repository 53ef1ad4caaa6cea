//! `mktree`, the command line: parses arguments, calls one library function
//! per subcommand, prints a table or JSON. Errors print one line and exit 1;
//! a closed pipe (`mktree dump F --json | head`) ends it quietly, by SIGPIPE.

mod args;
mod chart;
mod cmd;
mod input;
mod memory;
mod output;

use clap::Parser;

fn main() {
    quiet_on_broken_pipe();
    let cli = args::Cli::parse();
    if let Err(e) = cmd::run(cli) {
        // One line: the error and its causes, outermost first.
        let chain: Vec<String> = e.chain().map(|c| c.to_string()).collect();
        eprintln!("mktree: error: {}", chain.join(": "));
        std::process::exit(1);
    }
}

/// Rust ignores SIGPIPE, so a write to a closed pipe fails and `println!`
/// panics; the default action ends the process the way `cat` or `grep` end
/// (status 141 in a shell). Writes to files are transactional, so a build
/// ended this way leaves the previous tree.
#[cfg(unix)]
fn quiet_on_broken_pipe() {
    // SAFETY: called first in main, before any thread starts; SIG_DFL is a
    // valid action for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[cfg(not(unix))]
fn quiet_on_broken_pipe() {}
