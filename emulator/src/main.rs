fn main() {
    println!("drive-emu: under construction");
}
