//! The `mock-lab` binary: runs the simulated bench until stopped.

fn main() {
    eprintln!("mock-lab: under construction");
    std::process::exit(2);
}
