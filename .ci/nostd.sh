# Sourced by .ci/run: proves ecdc-core needs neither std nor alloc by building it for a bare-metal target.
if rustup target list --installed | grep -q thumbv7em-none-eabihf; then
    if cargo build -p ecdc-core --target thumbv7em-none-eabihf --release; then layer no_std passed; else layer no_std failed; fi
else
    layer no_std "skipped: thumbv7em-none-eabihf target not installable"
fi
