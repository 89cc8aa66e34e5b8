"""Read what a test needs from a shared library of another platform, in plain Python.

No tool of the target platform is needed (no otool, dumpbin or wine): the fields are
read from the file formats as their specifications lay them out.

- :func:`pe_info`: a PE32+ DLL (win64): machine, exported names, imported DLLs.
- :func:`macho_info`: a 64-bit Mach-O dylib (darwin64): CPU, file type, exported
  symbols, linked dylibs, minimum macOS version.
- :func:`elf_glibc_versions`: the GLIBC_x.y symbol versions an ELF binary requires.
- :func:`elf_machine`: the ELF machine (EM_X86_64, EM_AARCH64).
"""
import re
import struct


def _cstr(data, off):
    end = data.index(b"\0", off)
    return data[off:end].decode("latin-1")


def pe_info(path):
    """{"machine", "is_dll", "exports": [names], "imports": [DLL names]} of a PE32+ file."""
    data = open(path, "rb").read()
    if data[:2] != b"MZ":
        raise ValueError(f"{path}: not a PE file (no MZ header)")
    pe = struct.unpack_from("<I", data, 0x3C)[0]
    if data[pe:pe + 4] != b"PE\0\0":
        raise ValueError(f"{path}: no PE signature")
    machine, nsec, _, _, _, opt_size, chars = struct.unpack_from("<HHIIIHH", data, pe + 4)
    opt = pe + 24
    if struct.unpack_from("<H", data, opt)[0] != 0x20B:
        raise ValueError(f"{path}: not PE32+ (64-bit)")
    ndirs = struct.unpack_from("<I", data, opt + 108)[0]
    dirs = [struct.unpack_from("<II", data, opt + 112 + 8 * i) for i in range(ndirs)]
    sections = []
    for i in range(nsec):
        s = opt + opt_size + 40 * i
        vsize, vaddr, rsize, raddr = struct.unpack_from("<IIII", data, s + 8)
        sections.append((vaddr, max(vsize, rsize), raddr))

    def off(rva):
        for vaddr, size, raddr in sections:
            if vaddr <= rva < vaddr + size:
                return rva - vaddr + raddr
        raise ValueError(f"{path}: RVA {rva:#x} in no section")

    exports = []
    if ndirs > 0 and dirs[0][0]:
        e = off(dirs[0][0])
        n_names, names_rva = struct.unpack_from("<I", data, e + 24)[0], struct.unpack_from("<I", data, e + 32)[0]
        for i in range(n_names):
            exports.append(_cstr(data, off(struct.unpack_from("<I", data, off(names_rva) + 4 * i)[0])))
    imports = []
    if ndirs > 1 and dirs[1][0]:
        d = off(dirs[1][0])
        while True:
            name_rva = struct.unpack_from("<I", data, d + 12)[0]
            if name_rva == 0:
                break
            imports.append(_cstr(data, off(name_rva)))
            d += 20
    return {"machine": machine, "is_dll": bool(chars & 0x2000), "exports": exports, "imports": imports}


MH_MAGIC_64 = 0xFEEDFACF
CPU_TYPE_X86_64 = 0x01000007
CPU_TYPE_ARM64 = 0x0100000C
MH_DYLIB = 6
LC_SYMTAB, LC_LOAD_DYLIB, LC_VERSION_MIN_MACOSX, LC_BUILD_VERSION = 0x2, 0xC, 0x24, 0x32
N_EXT, N_PEXT, N_TYPE, N_SECT = 0x01, 0x10, 0x0E, 0x0E


def macho_info(path):
    """{"cputype", "filetype", "exports", "dylibs", "min_macos"} of a 64-bit Mach-O file.

    ``exports``: the external symbols defined in a section (names without the leading
    underscore the C compiler adds), not the private-extern ones.
    """
    data = open(path, "rb").read()
    magic, cputype, _, filetype, ncmds, _, _ = struct.unpack_from("<IiiIIII", data, 0)
    if magic != MH_MAGIC_64:
        raise ValueError(f"{path}: not a 64-bit little-endian Mach-O file")
    at = 32
    exports, dylibs, min_macos = [], [], None
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, at)
        if cmd == LC_SYMTAB:
            symoff, nsyms, stroff, _ = struct.unpack_from("<IIII", data, at + 8)
            for i in range(nsyms):
                strx, ntype, _sect, _desc, _value = struct.unpack_from("<IBBHQ", data, symoff + 16 * i)
                if ntype & N_EXT and not ntype & N_PEXT and (ntype & N_TYPE) == N_SECT:
                    name = _cstr(data, stroff + strx)
                    exports.append(name[1:] if name.startswith("_") else name)
        elif cmd == LC_LOAD_DYLIB:
            name_off = struct.unpack_from("<I", data, at + 8)[0]
            dylibs.append(_cstr(data, at + name_off))
        elif cmd in (LC_VERSION_MIN_MACOSX, LC_BUILD_VERSION):
            v = struct.unpack_from("<I", data, at + (8 if cmd == LC_VERSION_MIN_MACOSX else 12))[0]
            min_macos = (v >> 16, (v >> 8) & 0xFF)
        at += size
    return {"cputype": cputype, "filetype": filetype, "exports": exports, "dylibs": dylibs,
            "min_macos": min_macos}


def elf_glibc_versions(path):
    """The GLIBC_x.y versions named in an ELF binary (its version needs), as sorted tuples."""
    data = open(path, "rb").read()
    if data[:4] != b"\x7fELF":
        raise ValueError(f"{path}: not an ELF file")
    found = {tuple(int(x) for x in m.group(1).split(b"."))
             for m in re.finditer(rb"GLIBC_(\d+(?:\.\d+)+)\0", data)}
    return sorted(found)


EM_X86_64, EM_AARCH64 = 62, 183


def elf_machine(path):
    """The e_machine field of a 64-bit little-endian ELF file (EM_X86_64, EM_AARCH64, ...)."""
    data = open(path, "rb").read(20)
    if data[:4] != b"\x7fELF" or data[4] != 2 or data[5] != 1:
        raise ValueError(f"{path}: not a 64-bit little-endian ELF file")
    return struct.unpack_from("<H", data, 18)[0]
