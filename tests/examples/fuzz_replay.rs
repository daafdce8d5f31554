//! Replays fuzz inputs: `cargo run -p srug-tests --example fuzz_replay TARGET FILE...`
//! runs TARGET (see `srug_tests::fuzz::TARGETS`) on each file with the fuzz limits,
//! so a finding's panic shows its message and backtrace.

fn main() {
    let mut args = std::env::args().skip(1);
    let name = args.next().unwrap_or_default();
    let Some(target) = srug_tests::fuzz::TARGETS.iter().find(|t| t.name == name) else {
        let names: Vec<_> = srug_tests::fuzz::TARGETS.iter().map(|t| t.name).collect();
        eprintln!("usage: fuzz_replay TARGET FILE... (targets: {})", names.join(", "));
        std::process::exit(2);
    };
    srug::io::set_limits(srug_tests::fuzz::fuzz_limits());
    for file in args {
        match std::fs::read(&file) {
            Ok(bytes) => {
                (target.run)(&bytes);
                println!("{file}: no panic");
            }
            Err(e) => eprintln!("{file}: {e}"),
        }
    }
}
