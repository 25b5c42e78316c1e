# Sourced by .ci/run. ecdc-core is publish-ready: `cargo publish --dry-run` packages and builds
# it (with its README, licences and changelog), and the crate builds with exactly the toolchain
# its `rust-version` names (the MSRV users are promised).
msrv="$(sed -n 's/^rust-version = "\(.*\)"/\1/p' Cargo.toml | head -1)"
ok=1
if ! cargo publish --dry-run -p ecdc-core --allow-dirty; then ok=0; echo "publish dry-run failed"; fi
if [ -n "$msrv" ] && { rustup toolchain list | grep -q "^$msrv" || rustup toolchain install "$msrv" --profile minimal; }; then
    if ! CARGO_TARGET_DIR=target/msrv cargo "+$msrv" build -p ecdc-core; then ok=0; echo "ecdc-core does not build with Rust $msrv"; fi
else
    ok=0; echo "could not install Rust $msrv (rust-version)"
fi
if [ "$ok" = 1 ]; then layer publish passed; else layer publish failed; fi
