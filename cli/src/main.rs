//! `mktree`, the command line: parses arguments, calls one library function
//! per subcommand, prints a table or JSON. Errors print one line and exit 1.

mod args;
mod chart;
mod cmd;
mod output;

use clap::Parser;

fn main() {
    let cli = args::Cli::parse();
    if let Err(e) = cmd::run(cli) {
        // One line: the error and its causes, outermost first.
        let chain: Vec<String> = e.chain().map(|c| c.to_string()).collect();
        eprintln!("mktree: error: {}", chain.join(": "));
        std::process::exit(1);
    }
}
