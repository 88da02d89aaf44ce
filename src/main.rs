fn main() {
    // A closed stdout (e.g. `granrepro dag | head`) ends the program quietly; any other
    // panic is a bug: report it as such, exit 1.
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| info.payload().downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default();
        if !msg.contains("Broken pipe") {
            eprintln!("internal error (please report): {info}");
        }
    }));
    let code = match std::panic::catch_unwind(granrepro::cli::main) {
        Ok(code) => code,
        Err(p) => {
            let msg = p.downcast_ref::<String>().cloned().unwrap_or_default();
            if msg.contains("Broken pipe") { 0 } else { 1 }
        }
    };
    std::process::exit(code);
}
