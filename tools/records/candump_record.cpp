// A candump .log decoded with a DBC as an experiment record (msid frf --dbc): rows clocked by the
// frames of one message, lost frames as NaN rows (the FRF job rejects and counts the periods they
// touch), every other column sampled at its latest value.
#include "msid_candump_dbc.hpp"
#include "records_detail.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace msidrec {

namespace {

// One column of the record: which signal, and its latest value.
struct Col {
    std::string target, spec;
    const msid_dbc_signal *sig = nullptr;
    const msid_dbc_message *msg = nullptr;
    double value = std::numeric_limits<double>::quiet_NaN();
    bool have = false;
};

// Step 1: the column map as DBC signals, inputs first (u1..u_nu, y1..y_ny).
std::vector<Col> resolve(const DbcFile &dbc, const ColumnMap &cols, uint32_t &nu, uint32_t &ny)
{
    if (cols.empty())
        throw ColumnSpecError(MSID_OPT("dbc") " needs " MSID_OPT("columns") " u1=MESSAGE.SIGNAL,...,y1=MESSAGE.SIGNAL,... (the signals of '" +
                              dbc.path() + "' that are the inputs and outputs)");
    nu = ny = 0;
    for (const auto &kv : cols.map) (kv.first[0] == 'u' || kv.first[0] == 'U' ? nu : ny)++;
    if (nu == 0 && !cols.inputs_optional) throw ColumnSpecError(MSID_OPT("columns") " names no input (u1=MESSAGE.SIGNAL)");
    if (ny == 0) throw ColumnSpecError(MSID_OPT("columns") " names no output (y1=MESSAGE.SIGNAL)");
    std::vector<Col> out(nu + ny);
    for (const auto &kv : cols.map) {
        const bool in = kv.first[0] == 'u' || kv.first[0] == 'U';
        const size_t k = std::stoul(kv.first.substr(1)) - 1 + (in ? 0 : nu);
        Col &c = out.at(k);
        c.target = kv.first;
        c.spec = kv.second;
        c.sig = &dbc.signal(kv.second, kv.first);
        c.msg = &dbc.db().messages[c.sig->message];
    }
    return out;
}

// Step 2: the row message's sample interval in ns: the median of its frame intervals (the DBC's cycle
// time when the log has fewer than two intervals; 0 when neither is known).
uint64_t row_interval(const std::string &path, const msid_dbc_message &row, uint64_t &n_frames, uint64_t &lines,
                      std::vector<std::string> &notes)
{
    std::vector<uint64_t> t;
    for_each_candump_frame(path, [&](const msid_can_frame &f, uint64_t line) {
        lines = line;
        if (!(f.id & MSID_CAN_ERR_FLAG) && (f.id & (MSID_CAN_EFF_FLAG | 0x1FFFFFFFu)) == row.id) t.push_back(f.t_ns);
        return true;
    });
    n_frames = t.size();
    if (t.empty()) return 0;
    std::vector<uint64_t> d;
    for (size_t k = 1; k < t.size(); ++k) d.push_back(t[k] > t[k - 1] ? t[k] - t[k - 1] : 0);
    const uint64_t cyc = (uint64_t)row.cycle_ms * 1000000u;
    if (d.size() < 2) return cyc;
    std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
    const uint64_t med = d[d.size() / 2];
    if (cyc && (med * 4 < cyc * 3 || med * 4 > cyc * 5))
        notes.push_back(fmt("'%s': message %s comes every %.6g ms in the log but its GenMsgCycleTime is %u ms: lost "
                            "frames are found from the log's interval",
                            path.c_str(), row.name, (double)med / 1e6, (unsigned)row.cycle_ms));
    return med;
}

}  // namespace

Record read_record_candump(const std::string &path, const DbcFile &dbc, const ColumnMap &cols,
                           std::vector<std::string> &notes, CandumpCounts *counts)
{
    uint32_t nu = 0, ny = 0;
    std::vector<Col> col = resolve(dbc, cols, nu, ny);
    const msid_dbc_message &row = *col[0].msg;
    CandumpCounts n;
    uint64_t lines = 0;
    const uint64_t T = row_interval(path, row, n.row_frames, lines, notes);
    if (n.row_frames == 0)
        throw Error(fmt("'%s': no frame of message %s (identifier 0x%X, column %s=%s) in its %llu lines", path.c_str(),
                        row.name, (unsigned)(row.id & 0x1FFFFFFFu), col[0].target.c_str(), col[0].spec.c_str(),
                        (unsigned long long)lines));
    n.interval_s = (double)T / 1e9;
    const size_t C = nu + ny;
    Record r;
    r.path = path;
    r.nu = nu;
    r.ny = ny;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    auto push_nan = [&](uint64_t k) { r.rows.insert(r.rows.end(), (size_t)k * C, nan); };
    uint64_t t_prev = 0;
    bool first = true;
    std::vector<uint8_t> msg_used(dbc.db().n_messages, 0);
    for (const Col &c : col) msg_used[(size_t)(c.msg - dbc.db().messages)] = 1;
    // Step 3: the frames in file order; a row at each frame of the row message
    for_each_candump_frame(path, [&](const msid_can_frame &f, uint64_t) {
        ++n.frames;
        if (f.id & MSID_CAN_ERR_FLAG) {
            ++n.error_frames;
            return true;
        }
        if (f.id & MSID_CAN_RTR_FLAG) return true;   // a remote request carries no signal
        const msid_dbc_message *m = msid_dbc_message_by_id(&dbc.db(), f.id & (MSID_CAN_EFF_FLAG | 0x1FFFFFFFu));
        if (!m) {
            ++n.unknown_ids;
            return true;
        }
        if (!msg_used[(size_t)(m - dbc.db().messages)]) return true;
        bool is_short = false;
        for (Col &c : col) {
            if (c.msg != m) continue;
            const int pr = msid_dbc_present(&dbc.db(), c.sig, f.data, f.len);
            double v;
            if (pr == 1 && msid_dbc_decode(c.sig, f.data, f.len, &v) == 0) {
                c.value = v;
                c.have = true;
            } else if (pr != 0) {
                is_short = true;   // the frame ends before the signal (or its multiplexer)
            }
        }
        if (m != &row) return true;
        if (!first && T) {
            const uint64_t dt = f.t_ns > t_prev ? f.t_ns - t_prev : 0;
            if (dt * 2 > 3 * T) {   // over 1.5 intervals: llround(dt / T) - 1 samples are missing
                const uint64_t miss = (dt + T / 2) / T - 1;
                push_nan(miss);
                n.lost += miss;
                ++n.gaps;
            }
        }
        first = false;
        t_prev = f.t_ns;
        bool all = true, finite = true;
        for (const Col &c : col) {
            all = all && c.have;
            finite = finite && std::isfinite(c.value);
        }
        if (is_short) {
            ++n.short_frames;
            push_nan(1);
        } else if (!all) {
            ++n.before_values;
            push_nan(1);
        } else {
            if (!finite) ++n.nonfinite;
            for (const Col &c : col) r.rows.push_back(std::isfinite(c.value) ? c.value : nan);
        }
        return true;
    });
    r.n_rows = r.rows.size() / C;
    for (const Col &c : col)
        r.columns.push_back(c.sig->unit[0] ? std::string(c.sig->name) + " [" + c.sig->unit + "]" : std::string(c.sig->name));
    // Step 4: what was counted, one note each
    const std::string rowmsg = fmt("'%s': message %s", path.c_str(), row.name);
    if (n.lost)
        notes.push_back(fmt("%s: %llu frame(s) lost in %llu gap(s) (over 1.5 times its interval of %.6g ms): NaN rows, "
                            "the periods they touch are rejected, never interpolated",
                            rowmsg.c_str(), (unsigned long long)n.lost, (unsigned long long)n.gaps, n.interval_s * 1e3));
    if (n.short_frames)
        notes.push_back(fmt("%s: %llu frame(s) shorter than a column's signal: NaN rows (rejected periods)",
                            rowmsg.c_str(), (unsigned long long)n.short_frames));
    if (n.before_values)
        notes.push_back(fmt("%s: the first %llu row(s) come before every column has a value: NaN rows (rejected periods)",
                            rowmsg.c_str(), (unsigned long long)n.before_values));
    if (n.nonfinite)
        notes.push_back(fmt("%s: %llu row(s) hold a NaN or infinite float signal (rejected periods)", rowmsg.c_str(),
                            (unsigned long long)n.nonfinite));
    if (n.unknown_ids)
        notes.push_back(fmt("'%s': %llu frame(s) of identifiers '%s' does not define were left out", path.c_str(),
                            (unsigned long long)n.unknown_ids, dbc.path().c_str()));
    if (n.error_frames)
        notes.push_back(fmt("'%s': %llu error frame(s) in the log", path.c_str(), (unsigned long long)n.error_frames));
    if (counts) *counts = n;
    return r;
}

}  // namespace msidrec
