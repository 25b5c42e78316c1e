fn main() {
    println!("ecdc: under construction");
}
