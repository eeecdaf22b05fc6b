/*
 * fogtrace: a QEMU TCG plugin (plugin API version 1, QEMU 7.x) that writes the address of
 * every executed guest instruction, in execution order, as little-endian u32 to the file
 * named by its `out=PATH` argument. Used by the cycle estimate (tests/src/cycles.rs,
 * `fw-cycles`). One vCPU only (the Cortex-M boards have one).
 *
 * QEMU's Debian package ships the plugin interface in the binary but no header, so the few
 * declarations used are written here from the documented API (docs/devel/tcg-plugins.rst of
 * QEMU 7.2): a plugin exports `qemu_plugin_version` and `qemu_plugin_install`; at each
 * translation it registers an execution callback per instruction, called only when that
 * instruction executes (an instruction QEMU re-translates for I/O under -icount is not
 * counted twice: the re-executed part is instrumented for memory only).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef uint64_t qemu_plugin_id_t;
struct qemu_plugin_tb;
struct qemu_plugin_insn;
typedef struct qemu_info_t qemu_info_t;
enum qemu_plugin_cb_flags { CB_NO_REGS, CB_R_REGS, CB_RW_REGS };
typedef void (*tb_trans_cb)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
typedef void (*udata_cb)(unsigned int vcpu_index, void *userdata);
typedef void (*exit_cb)(qemu_plugin_id_t id, void *userdata);

extern void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, tb_trans_cb cb);
extern size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
extern struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb,
                                                        size_t idx);
extern uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *insn);
extern void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *insn, udata_cb cb,
                                                   enum qemu_plugin_cb_flags flags,
                                                   void *userdata);
extern void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, exit_cb cb, void *userdata);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

static FILE *out;
static uint32_t buf[1 << 16];
static size_t used;

static void flush_buf(void)
{
    if (used && fwrite(buf, sizeof buf[0], used, out) != used) {
        perror("fogtrace: write");
        exit(1);
    }
    used = 0;
}

static void on_exec(unsigned int vcpu_index, void *userdata)
{
    (void)vcpu_index;
    /* The host is little-endian (x86-64, aarch64): the file is little-endian u32. */
    buf[used++] = (uint32_t)(uintptr_t)userdata;
    if (used == sizeof buf / sizeof buf[0]) {
        flush_buf();
    }
}

static void on_translate(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    (void)id;
    size_t n = qemu_plugin_tb_n_insns(tb);
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uintptr_t pc = (uintptr_t)qemu_plugin_insn_vaddr(insn);
        qemu_plugin_register_vcpu_insn_exec_cb(insn, on_exec, CB_NO_REGS, (void *)pc);
    }
}

static void on_atexit(qemu_plugin_id_t id, void *userdata)
{
    (void)id;
    (void)userdata;
    flush_buf();
    fclose(out);
}

__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id,
                                                               const qemu_info_t *info,
                                                               int argc, char **argv)
{
    (void)info;
    const char *path = NULL;
    for (int i = 0; i < argc; i++) {
        if (strncmp(argv[i], "out=", 4) == 0) {
            path = argv[i] + 4;
        }
    }
    if (!path) {
        fprintf(stderr, "fogtrace: argument out=PATH is required\n");
        return -1;
    }
    out = fopen(path, "wb");
    if (!out) {
        perror("fogtrace: open");
        return -1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_translate);
    qemu_plugin_register_atexit_cb(id, on_atexit, NULL);
    return 0;
}
