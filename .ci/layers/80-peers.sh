# Sourced by .ci/run: the other masters (peers/, each its own Cargo workspace). Both drivers
# must build: peers/ethercrab-driver (ethercrab from crates.io) and peers/soem-driver (SOEM's C
# sources from the SOEM-sys crate, built by its build script with cmake + libclang, which
# .ci/install.sh installs; GPL-2.0, never linked into an ecdc crate); peers/ethercrab-ecdc
# must pass clippy, fmt and its tests. Then, when root and
# network namespaces work, scripts/peers-bench.sh runs on seed 003's two servo slaves for 2 s
# each, one run (PEERS_REPEATS=1): ethercrab to OP with DC, and SOEM's ec_config_init +
# ec_config_map + ec_configdc. The layer checks the emulator's JSON (`sync` figures present,
# SYNC0 firing on both slaves under ethercrab, every slave in OP) and that the identities each
# master read from SII are the ones the emulated EEPROMs hold. Skips the netns part, with the
# reason, when not root or without netns/veth.
peers_status=passed
# SOEM 1.3.3's CMakeLists asks for cmake 2.8.4, which cmake >= 4 refuses without this.
if cmake --version 2>/dev/null | head -n1 | grep -q 'version [4-9]'; then
    export CMAKE_POLICY_VERSION_MINIMUM=3.5
fi
peers_target="${CARGO_TARGET_DIR:-$PWD/target}"
for d in ethercrab-driver soem-driver; do
    if (cd "peers/$d" && CARGO_TARGET_DIR="$peers_target" cargo build -q --release \
        && CARGO_TARGET_DIR="$peers_target" cargo clippy -q --release -- -D warnings \
        && cargo fmt --check); then
        echo "peers/$d builds, clippy and fmt clean"
    else
        peers_status="failed (peers/$d build, clippy or fmt)"
    fi
done
# peers/ethercrab-ecdc embeds ecdc-core in ethercrab's TX/RX loop; its tests run that whole
# master against the emulator in-process (no network), including a re-initialisation in OP.
if (cd peers/ethercrab-ecdc \
    && CARGO_TARGET_DIR="$peers_target" cargo clippy -q --release --all-targets -- -D warnings \
    && cargo fmt --check && CARGO_TARGET_DIR="$peers_target" cargo test -q --release); then
    echo "peers/ethercrab-ecdc: clippy, fmt and tests pass"
else
    peers_status="failed (peers/ethercrab-ecdc clippy, fmt or tests)"
fi
if [ "$peers_status" = passed ]; then
    peers_out="$(mktemp -d)"
    peers_log="$(mktemp)"
    PEERS_NO_BUILD=1 PEERS_REPEATS=1 PEERS_MASTERS="ethercrab soem-config" PEERS_OUT="$peers_out" \
        bash -c 'cargo build -q --release -p ecdc-harness --bin ecdc && exec bash scripts/peers-bench.sh 2 seed003-line2' \
        2>&1 | tee "$peers_log"
    peers_rc=${PIPESTATUS[0]}
    case "$peers_rc" in
        0)
            j="$peers_out/peers.json"
            # ethercrab: OP, SYNC0 on both slaves, the yardstick's figures present.
            if ! jq -e '.runs[] | select(.master == "ethercrab") | .exit == 0 and .al_states == ["OP"]
                    and .sync.slaves_firing == 2 and .sync.pairs > 0 and .sync.skew_max_ns != null
                    and .sync.skew_p99_ns != null' "$j" >/dev/null; then
                peers_status="failed (ethercrab not in OP with SYNC0 on both slaves, or no sync JSON)"
            fi
            if ! jq -e '.runs[] | select(.master == "soem-config") | .exit == 0
                    and any(.master_log[]; test("ec_config_init found 2 slaves"))
                    and any(.master_log[]; test("ec_configdc found DC slaves"))' "$j" >/dev/null; then
                peers_status="failed (SOEM ec_config_init / ec_configdc)"
            fi
            # Identities: what each master printed from SII = what the emulated EEPROMs hold.
            for m in ethercrab soem-config; do
                want="$(jq -r --arg m "$m" '.runs[] | select(.master == $m) | .identities[]
                    | [.vendor, .product] | @tsv' "$j" | awk '{printf "vendor 0x%08x product 0x%08x\n", $1, $2}')"
                got="$(jq -r --arg m "$m" '.runs[] | select(.master == $m) | .master_log[]' "$j" |
                    grep -o 'vendor 0x[0-9a-f]* product 0x[0-9a-f]*')"
                if [ -z "$want" ] || [ "$want" != "$got" ]; then
                    echo "identities differ for $m: emulator"; echo "$want"; echo "master"; echo "$got"
                    peers_status="failed ($m identities from SII)"
                else
                    echo "$m read the emulated SII identities: $(echo "$got" | tr '\n' ';')"
                fi
            done
            ;;
        77) peers_status="passed (netns part skipped: $(grep -m1 '^SKIP:' "$peers_log" | sed 's/^SKIP: //'))" ;;
        *) peers_status="failed (scripts/peers-bench.sh exit $peers_rc)" ;;
    esac
    rm -rf "$peers_out" "$peers_log"
fi
layer peers "$peers_status"
