#include "msid_cancel.hpp"

namespace msidutil {

static thread_local Cancel *tls_cancel = nullptr;

CancelScope::CancelScope(Cancel *c) : prev_(tls_cancel) { tls_cancel = c; }
CancelScope::~CancelScope() { tls_cancel = prev_; }

Cancel *current_cancel() { return tls_cancel; }

void checkpoint(Step step, uint64_t n, const char *where)
{
    Cancel *c = tls_cancel;
    if (c && c->proceed_or_stop(step, n)) throw Cancelled{where};
}

}  // namespace msidutil
