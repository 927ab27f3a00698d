# Shared by the scripts that cross-build for thumbv7em-none-eabihf (sourced, not run).
# The same two routes as scripts/fw-build (see /work/shared/TOOLCHAIN.md):
#   rustup: the rustup target is installed -> plain `cargo build --target`;
#   debian: Debian's rustc 1.96 + std sources with `-Zbuild-std=core`, in its own target dir,
#           the Debian packages installed when missing.
# After `cross_select_route`, `cross_cargo_build ARGS...` builds and `$CROSS_ROUTE` /
# `$CROSS_TARGET_SUBDIR` say which route and target-dir suffix were chosen.
# Environment: FW_ROUTE=rustup|debian forces a route (the name fw-build uses).

CROSS_TARGET=thumbv7em-none-eabihf
CROSS_DEBIAN_PACKAGES=(rustc-web cargo-web rust-web-src lld-22 binutils-arm-none-eabi)

cross_log() { printf '%s: %s\n' "${CROSS_LOG_NAME:-cross}" "$*" >&2; }

cross_have_rustup_target() {
    command -v rustup >/dev/null 2>&1 &&
        rustup target list --installed 2>/dev/null | grep -qx "$CROSS_TARGET"
}

# Runs a command as root: directly when we are root, through sudo when it exists.
cross_as_root() {
    if [ "$(id -u)" -eq 0 ]; then
        "$@"
    elif command -v sudo >/dev/null 2>&1; then
        sudo "$@"
    else
        cross_log "need root to run: $* (no sudo available)"
        exit 1
    fi
}

# Installs the named Debian packages that are not installed yet.
cross_ensure_packages() {
    local missing=()
    for pkg in "$@"; do
        dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q 'install ok installed' ||
            missing+=("$pkg")
    done
    if [ "${#missing[@]}" -gt 0 ]; then
        cross_log "installing ${missing[*]}"
        cross_as_root apt-get update
        cross_as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y "${missing[@]}"
    fi
}

cross_select_route() {
    CROSS_ROUTE=${FW_ROUTE:-}
    if [ -z "$CROSS_ROUTE" ]; then
        if cross_have_rustup_target; then CROSS_ROUTE=rustup; else CROSS_ROUTE=debian; fi
    fi
    case "$CROSS_ROUTE" in
        rustup) CROSS_TARGET_SUBDIR=rustup ;;
        debian)
            cross_ensure_packages "${CROSS_DEBIAN_PACKAGES[@]}"
            for tool in /usr/bin/rustc /usr/bin/cargo /usr/bin/rust-lld; do
                [ -x "$tool" ] || { cross_log "$tool missing after install"; exit 1; }
            done
            CROSS_TARGET_SUBDIR=debian
            ;;
        *) cross_log "FW_ROUTE must be rustup or debian, not '$CROSS_ROUTE'"; exit 2 ;;
    esac
}

# Target spec (Debian route). rustc's built-in thumbv7em-none-eabihf spec says
# "frame-pointer": "always" (and `-Cforce-frame-pointers` can only add frame pointers, never
# remove them): every function with a frame then sets up r7 as a frame pointer and has one
# register less. Nothing here walks frame pointers (probe-rs and defmt unwind with the ELF's
# DWARF CFI; the stack bound reads the disassembly), so the Debian route, which rebuilds core
# anyway (-Zbuild-std), builds for a copy of that spec with "may-omit" (1.9 KiB less flash,
# ≈ 100 B less stack per task) and with the chip's core named, "cpu": "cortex-m4" (the
# built-in spec leaves it generic ARMv7E-M; LLVM's Cortex-M4 model: 0.2 KiB less flash);
# BENCHMARKS.md "Firmware footprint". The copy is named like the built-in target, so cargo's
# output paths (<target-dir>/thumbv7em-none-eabihf/...) and CARGO_TARGET_THUMBV7EM_NONE_EABIHF_*
# settings stay the same; it is rewritten only when the compiler's spec changes (an unchanged
# file keeps cargo's fingerprints). FW_FRAME_POINTERS=keep builds for the built-in target
# instead.
cross_target_spec() {
    if [ "${FW_FRAME_POINTERS:-omit}" = keep ]; then
        printf '%s\n' "$CROSS_TARGET"
        return
    fi
    local dir=${CARGO_TARGET_DIR:-$PWD/target}/target-spec
    local spec=$dir/$CROSS_TARGET.json
    mkdir -p "$dir"
    RUSTC_BOOTSTRAP=1 /usr/bin/rustc -Zunstable-options --print target-spec-json \
        --target "$CROSS_TARGET" >"$spec.new"
    if grep -q '"cpu"' "$spec.new" || ! grep -q '"frame-pointer": "always",' "$spec.new"; then
        # A compiler whose spec already differs: build for its built-in target rather than
        # guess at an edit (larger flash and stack, same code).
        cross_log "target spec: not the expected built-in spec (rustc changed?), using the built-in target: $spec.new"
        printf '%s\n' "$CROSS_TARGET"
        return
    fi
    sed -i 's/"frame-pointer": "always",/"cpu": "cortex-m4",\n  "frame-pointer": "may-omit",/' "$spec.new"
    if cmp -s "$spec.new" "$spec"; then rm "$spec.new"; else mv "$spec.new" "$spec"; fi
    printf '%s\n' "$spec"
}

cross_cargo_build() {
    if [ "$CROSS_ROUTE" = rustup ]; then
        cargo build --release --target "$CROSS_TARGET" "$@"
    else
        local target json_flag=()
        target=$(cross_target_spec)
        [ "$target" = "$CROSS_TARGET" ] || json_flag=(-Zjson-target-spec)
        # -Zbuild-std belongs on the command line, never in .cargo/config.toml [unstable]:
        # with RUSTC_BOOTSTRAP=1 that would break host builds (TOOLCHAIN.md).
        RUSTC=/usr/bin/rustc RUSTDOC=/usr/bin/rustdoc RUSTC_BOOTSTRAP=1 \
            /usr/bin/cargo build --release -Zbuild-std=core "${json_flag[@]}" \
            --target "$target" "$@"
    fi
}
