//! `host-sim`: run the lift's digital twin from the command line (the subcommands:
//! [`host_sim::commands`]).

fn main() -> std::process::ExitCode {
    host_sim::commands::main()
}
