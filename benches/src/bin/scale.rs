//! Scale report (issue 8 item 4); being written.

fn main() {
    eprintln!("scale: not implemented yet");
}
