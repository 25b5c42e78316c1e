# Sourced by .ci/run. Installs the system packages and cargo tools CI needs; idempotent.
export PATH="$HOME/.cargo/bin:$PATH"
need_apt=()
command -v tshark >/dev/null 2>&1 || need_apt+=(tshark)
[ -e /usr/include/z3.h ] || need_apt+=(libz3-dev)
command -v ip >/dev/null 2>&1 || need_apt+=(iproute2)
command -v jq >/dev/null 2>&1 || need_apt+=(jq)
command -v clang >/dev/null 2>&1 || need_apt+=(clang)
# the z3 crate generates its bindings with bindgen, which loads libclang
ls /usr/lib/llvm-*/lib/libclang.so* >/dev/null 2>&1 || need_apt+=(libclang-dev) # libclang.so, not libclang-cpp.so
if [ "${#need_apt[@]}" -gt 0 ]; then
    echo "wireshark-common wireshark-common/install-setuid boolean false" | debconf-set-selections 2>/dev/null || true
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need_apt[@]}" >/dev/null \
        || echo "warning: apt-get install ${need_apt[*]} failed"
fi
rustup component add clippy rustfmt >/dev/null 2>&1 || true
rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
rustup target list --installed | grep -q thumbv7em-none-eabihf || rustup target add thumbv7em-none-eabihf || true
if ! cargo fuzz --version >/dev/null 2>&1; then
    cargo install --locked cargo-fuzz >/dev/null 2>&1 || cargo install cargo-fuzz
fi
