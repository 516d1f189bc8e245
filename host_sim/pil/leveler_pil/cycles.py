"""Cortex-M3 cycle estimate of a translated block (Cortex-M3 TRM r2p1, table 18-1).

An upper-bound style estimate, used both as the emulator's time base and for
the tick cost: every branch that ends a block is counted as taken with the
worst pipeline refill (P = 3, which also covers the flash's 2 wait states on
a jump at 72 MHz), loads and stores 2 cycles, LDM/STM/PUSH/POP 1 + N
(+ P when they load the PC), divides 12 (their worst case), long multiplies 5.
"""

from capstone import CS_ARCH_ARM, CS_MODE_MCLASS, CS_MODE_THUMB, Cs

REFILL = 3
_cs = Cs(CS_ARCH_ARM, CS_MODE_THUMB + CS_MODE_MCLASS)
_cs.detail = False
_CONDS = ("eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le", "al")
_BRANCHES = {"b", "bl", "bx", "blx", "cbz", "cbnz"}


def _base(mnemonic):
    m = mnemonic.split(".")[0]
    if m in _BRANCHES or m in ("tbb", "tbh"):
        return m
    if len(m) > 2 and m[-2:] in _CONDS and m[:-2] in _BRANCHES | {"b"}:
        return m[:-2]          # beq, bne, ...
    return m


def _reg_count(op_str):
    return op_str.count(",") + 1 if "{" in op_str else 1


def insn_cycles(mnemonic, op_str):
    m = _base(mnemonic)
    writes_pc = op_str.startswith("pc") or "pc}" in op_str
    if m in _BRANCHES:
        return 1 + REFILL
    if m in ("tbb", "tbh"):
        return 2 + REFILL
    if m.startswith(("ldm", "pop", "stm", "push")):
        return 1 + _reg_count(op_str) + (REFILL if writes_pc else 0)
    if m.startswith(("ldrd", "strd")):
        return 3
    if m.startswith(("ldr", "str", "ldrex", "strex")):
        return 2 + (REFILL if writes_pc else 0)
    if m.startswith(("sdiv", "udiv")):
        return 12
    if m.startswith(("umull", "smull", "umlal", "smlal")):
        return 5
    if m.startswith(("mla", "mls")):
        return 2
    return 1 + (REFILL if writes_pc else 0)


def analyse_block(code, addr):
    """(instructions, cycles, spin) of the block at addr; spin = a lone branch to itself."""
    n = c = 0
    spin = False
    for insn in _cs.disasm(bytes(code), addr):
        n += 1
        c += insn_cycles(insn.mnemonic, insn.op_str)
        if insn.mnemonic.split(".")[0] == "b" and insn.op_str == f"#0x{addr:x}" and n == 1:
            spin = True
    return n, c, spin and n == 1


def _it_length(halfword):
    """Instructions an IT instruction covers (0 if halfword is not IT)."""
    if halfword & 0xFF00 != 0xBF00 or halfword & 0xF == 0:
        return 0
    mask = halfword & 0xF
    return 4 - (mask & -mask).bit_length() + 1


def starts_in_it_block(before, addr):
    """True when the instruction at addr is inside an IT block. before: the up
    to 16 code bytes that end at addr. An interrupt must not be taken there:
    resuming with emu_start would lose the IT state."""
    for back in range(2, len(before) + 1, 2):
        hw = int.from_bytes(before[len(before) - back:len(before) - back + 2], "little")
        n = _it_length(hw)
        if not n:
            continue
        covered = sum(1 for _ in _cs.disasm(bytes(before[len(before) - back + 2:]), addr - back + 2))
        if covered < n:
            return True
    return False
