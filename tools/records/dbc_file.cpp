// A DBC file read whole into memory the object owns (daq's msid_dbc: ask the size, then place), and
// the MESSAGE.SIGNAL names of a column map looked up in it.
#include "msid_candump_dbc.hpp"
#include "records_detail.hpp"

namespace msidrec {

DbcFile::DbcFile(const std::string &path) : path_(path)
{
    const FileBytes f(path);
    const size_t need = msid_dbc_mem_size(f.data(), f.size());
    if (need == 0) {   // not DBC syntax: init without memory names the line
        msid_dbc_init(&d_, f.data(), f.size(), nullptr, 0);
        throw Error("'" + path + "' " + d_.err);
    }
    mem_.assign((need + 7) / 8, 0);
    const int rc = msid_dbc_init(&d_, f.data(), f.size(), mem_.data(), mem_.size() * 8);
    if (rc) throw Error("'" + path + "' " + d_.err);
}

const msid_dbc_signal &DbcFile::signal(const std::string &spec, const std::string &target) const
{
    const size_t dot = spec.find('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 == spec.size() || spec.find('.', dot + 1) != std::string::npos)
        throw ColumnSpecError(MSID_OPT("columns") " " + target + "=" + spec +
                              ": with " MSID_OPT("dbc") " a column is MESSAGE.SIGNAL (a message and one of its signals in '" + path_ +
                              "')");
    const std::string msg = spec.substr(0, dot), sig = spec.substr(dot + 1);
    const msid_dbc_message *m = msid_dbc_message_by_name(&d_, msg.c_str());
    if (!m) throw ColumnSpecError(MSID_OPT("columns") " " + target + "=" + spec + ": '" + path_ + "' has no message " + msg);
    const msid_dbc_signal *s = msid_dbc_signal_by_name(&d_, m, sig.c_str());
    if (!s) {
        std::string have;
        for (uint32_t k = 0; k < m->n_signals && k < 12; ++k)
            have += std::string(k ? ", " : "") + d_.signals[m->first_signal + k].name;
        if (m->n_signals > 12) have += ", ...";
        throw ColumnSpecError(MSID_OPT("columns") " " + target + "=" + spec + ": message " + msg + " of '" + path_ +
                              "' has no signal " + sig + (have.empty() ? " (it has none)" : " (it has " + have + ")"));
    }
    return *s;
}

}  // namespace msidrec
