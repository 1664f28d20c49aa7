// The in-VM CANopen tests' probe: the library calls behind `msid device check|sdo|pdo` of a CANopen node
// (tools/acquire/msid_canopen.hpp) with positional arguments, in an executable that links only them.
//   co_probe check URI | read URI INDEX:SUB | write URI INDEX:SUB HEX | pdo URI tpdo|rpdo K LIST [TRANSMISSION [EDS]]
//   co_probe eds FILE: the entries msid reads from an EDS/DCF, one a line (index sub type access mappable)
//   co_probe sync IFACE PERIOD_US COUNTER SECONDS: SYNC by CAN_BCM for SECONDS (0: until killed), then stopped
// Output and exit status as the command's: the lines on stdout, one error line on stderr, 1 for the node
// or the bus, 2 for a bad request.
#include <cstdio>
#include <cstdlib>
#include <string>

#include "msid_canopen.hpp"
#include "msid_host_error.hpp"
#include "msid_daq/msid_co_eds.h"
#include "msid_daq/msid_co_sync.h"

#include <unistd.h>

static int run_sync(const char *iface, const char *period, const char *counter, const char *seconds)
{
    msid_co_sync s;
    if (msid_co_sync_start(&s, iface, (uint32_t)std::strtoul(period, nullptr, 10), (unsigned)std::strtoul(counter, nullptr, 10))) {
        std::fprintf(stderr, "co_probe: error: %s\n", s.err);
        return 1;
    }
    std::printf("started\n");
    std::fflush(stdout);
    const unsigned long sec = std::strtoul(seconds, nullptr, 10);
    if (!sec)
        for (;;) pause();
    sleep((unsigned)sec);
    msid_co_sync_stop(&s);
    std::printf("stopped\n");
    return 0;
}

static int dump_eds(const char *path)
{
    static msid_co_od_entry mem[4096];
    msid_co_eds eds;
    if (msid_co_eds_load(path, &eds, mem, 4096)) {
        std::fprintf(stderr, "co_probe: error: %s\n", eds.err);
        return 1;
    }
    static const char *const ACCESS[] = {"ro", "wo", "rw", "rwr", "rww", "const"};
    for (uint32_t i = 0; i < eds.n; i++)
        std::printf("%04X %02X %04X %s %u\n", (unsigned)eds.e[i].index, (unsigned)eds.e[i].sub, (unsigned)eds.e[i].type,
                    ACCESS[eds.e[i].access], (unsigned)eds.e[i].pdo_mappable);
    return 0;
}

int main(int argc, char **argv)
{
    try {
        const std::string op = argc > 2 ? argv[1] : "";
        if (op == "eds" && argc == 3) return dump_eds(argv[2]);
        if (op == "sync" && argc == 6) return run_sync(argv[2], argv[3], argv[4], argv[5]);
        if (op == "check" && argc == 3) {
            const msidacq::CanopenCheck r = msidacq::check_canopen(msidacq::parse_canopen_uri(argv[2]));
            for (const std::string &l : r.lines) std::printf("%s\n", l.c_str());
            return r.problems ? 1 : 0;
        }
        if ((op == "read" && argc == 4) || (op == "write" && argc == 5)) {
            const msidacq::CanopenUri uri = msidacq::parse_canopen_uri(argv[2]);
            const msidacq::CoEntry e = msidacq::parse_co_entry(argv[3]);
            msidacq::CanopenLink link(uri);
            if (op == "write") link.write(e, msidacq::parse_hex_bytes(argv[4], "data"));
            else std::printf("%s\n", msidacq::hex_bytes(link.read(e)).c_str());
            return 0;
        }
        if (op == "pdo" && argc >= 6 && argc <= 8) {
            msid_co_pdo_cfg c{};
            c.tx = std::string(argv[3]) == "tpdo";
            c.num = (uint16_t)std::strtoul(argv[4], nullptr, 10);
            c.trans_type = (uint8_t)(argc >= 7 ? std::strtoul(argv[6], nullptr, 0) : MSID_CO_PDO_SYNC_EVERY);
            msidacq::parse_pdo_map(argv[5], c);
            const std::string eds = argc == 8 ? argv[7] : "";
            std::printf("%s\n", msidacq::configure_pdo(msidacq::parse_canopen_uri(argv[2]), c, eds).c_str());
            return 0;
        }
        std::fprintf(stderr, "usage: co_probe check URI | read URI E | write URI E HEX | pdo URI tpdo|rpdo K LIST [T]\n");
        return 2;
    } catch (const msidutil::Error &e) {
        std::fprintf(stderr, "co_probe: error: %s\n", e.what());
        return e.code;
    }
}
