fn main() {
    std::process::exit(granrepro::cli::main());
}
