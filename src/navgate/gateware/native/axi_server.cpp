#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>
#include "V@TOP@.h"
#include "verilated.h"

static const int N_STREAMS = @N_STREAMS@;
static const int N_WATCH = @N_WATCH@;
static const int MAX_WORDS = @MAX_WORDS@;
static const int STREAM_WIDTH[] = {@STREAM_WIDTHS@};
static const uint32_t ADDR_MASK = @ADDR_MASK@u;

static V@TOP@* top;
static long total = 0;
static long limit = 100000;
static double delay_p = 0.0;
static int max_delay = 0;
static int skew = 0;
static uint64_t rng = 0x9E3779B97F4A7C15ull;
static std::string wedged;

static uint64_t next_rand() {  // splitmix64
    uint64_t z = (rng += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static int draw() {
    if (delay_p <= 0.0 || max_delay <= 0) return 0;
    double u = (double)(next_rand() >> 11) * (1.0 / 9007199254740992.0);
    if (u >= delay_p) return 0;
    return 1 + (int)(next_rand() % (uint64_t)max_delay);
}

static void set_stream_valid(int k, int v) {
    switch (k) {
@SET_VALID@
    default: break;
    }
}

static bool stream_ready(int k) {
    switch (k) {
@GET_READY@
    default: return false;
    }
}

static void set_stream_payload(int k, const uint32_t* w) {
    switch (k) {
@SET_PAYLOAD@
    default: break;
    }
}

static bool watched(int k) {
    switch (k) {
@GET_WATCH@
    default: return false;
    }
}

static void idle() {
    top->axi___05Fawvalid = 0; top->axi___05Fwvalid = 0; top->axi___05Fbready = 0;
    top->axi___05Farvalid = 0; top->axi___05Frready = 0;
    for (int k = 0; k < N_STREAMS; k++) set_stream_valid(k, 0);
}

static inline void settle() { top->clk = 0; top->eval(); }
static inline void edge() { top->clk = 1; top->eval(); total++; }

static std::string hex(uint64_t v) {
    char b[32];
    snprintf(b, sizeof b, "%lx", (unsigned long)v);
    return b;
}

static bool axi_write(uint32_t addr, uint32_t data, uint32_t strb, int& resp,
                      std::string& err) {
    int d_aw = draw(), d_w = draw(), d_b = draw();
    if (skew > 0) d_w += skew; else d_aw += -skew;
    top->axi___05Fawaddr = addr & ADDR_MASK; top->axi___05Fawprot = 0;
    top->axi___05Fwdata = data; top->axi___05Fwstrb = strb & 0xF;
    bool aw = false, w = false;
    long start = total;
    while (true) {
        bool both = aw && w;
        top->axi___05Fawvalid = !aw && d_aw == 0;
        top->axi___05Fwvalid = !w && d_w == 0;
        top->axi___05Fbready = both && d_b == 0;
        settle();
        bool aw_f = top->axi___05Fawvalid && top->axi___05Fawready;
        bool w_f = top->axi___05Fwvalid && top->axi___05Fwready;
        bool b_f = top->axi___05Fbready && top->axi___05Fbvalid;
        int r = top->axi___05Fbresp;
        edge();
        if (b_f) { resp = r; idle(); return true; }
        if (aw_f) aw = true; else if (!aw && d_aw) d_aw--;
        if (w_f) w = true; else if (!w && d_w) d_w--;
        if (both && d_b) d_b--;
        if (total - start >= limit) {
            err = std::string("write to 0x") + hex(addr) + ": no " +
                  (!aw ? "AW handshake" : !w ? "W handshake" : "B response") +
                  " within " + std::to_string(limit) + " cycles";
            wedged = err;
            return false;
        }
    }
}

static bool axi_read(uint32_t addr, uint32_t& data, int& resp, std::string& err) {
    int d_ar = draw(), d_r = draw();
    top->axi___05Faraddr = addr & ADDR_MASK; top->axi___05Farprot = 0;
    bool ar = false;
    long start = total;
    while (true) {
        bool was = ar;
        top->axi___05Farvalid = !ar && d_ar == 0;
        top->axi___05Frready = ar && d_r == 0;
        settle();
        bool ar_f = top->axi___05Farvalid && top->axi___05Farready;
        bool r_f = top->axi___05Frready && top->axi___05Frvalid;
        uint32_t d = top->axi___05Frdata;
        int r = top->axi___05Frresp;
        edge();
        if (r_f) { data = d; resp = r; idle(); return true; }
        if (ar_f) ar = true; else if (!ar && d_ar) d_ar--;
        if (was && d_r) d_r--;
        if (total - start >= limit) {
            err = std::string("read of 0x") + hex(addr) + ": no " +
                  (!ar ? "AR handshake" : "R response") + " within " +
                  std::to_string(limit) + " cycles";
            wedged = err;
            return false;
        }
    }
}

static bool push(int k, const uint32_t* w, std::string& err) {
    int d = draw();
    set_stream_payload(k, w);
    long start = total;
    while (true) {
        set_stream_valid(k, d == 0);
        settle();
        bool fire = d == 0 && stream_ready(k);
        edge();
        if (fire) { set_stream_valid(k, 0); return true; }
        if (d) d--;
        if (total - start >= limit) {
            err = "stream " + std::to_string(k) + " not ready within " +
                  std::to_string(limit) + " cycles";
            wedged = err;
            return false;
        }
    }
}

struct Cmd {
    char op;
    uint64_t a, b, c, d;
    std::vector<uint32_t> words;
    std::string text;
};

static bool parse_hex(const std::string& s, uint64_t& v, int max_digits) {
    if (s.empty() || (int)s.size() > max_digits) return false;
    v = 0;
    for (char ch : s) {
        int x;
        if (ch >= '0' && ch <= '9') x = ch - '0';
        else if ((ch | 0x20) >= 'a' && (ch | 0x20) <= 'f') x = (ch | 0x20) - 'a' + 10;
        else return false;
        v = (v << 4) | (uint64_t)x;
    }
    return true;
}

static bool parse_dec(const std::string& s, uint64_t& v) {
    if (s.empty() || s.size() > 18) return false;
    v = 0;
    for (char ch : s) {
        if (ch < '0' || ch > '9') return false;
        v = v * 10 + (uint64_t)(ch - '0');
    }
    return true;
}

static bool parse_words(const std::string& s, int width, std::vector<uint32_t>& w) {
    w.assign(MAX_WORDS, 0);
    int n = s.size();
    if (n == 0) return false;
    for (int i = 0; i < n; i++) {
        char ch = s[n - 1 - i];
        uint32_t x;
        if (ch >= '0' && ch <= '9') x = ch - '0';
        else if ((ch | 0x20) >= 'a' && (ch | 0x20) <= 'f') x = (ch | 0x20) - 'a' + 10;
        else return false;
        if (x == 0) continue;
        int top_bit = 4 * i + (x >= 8 ? 4 : x >= 4 ? 3 : x >= 2 ? 2 : 1);
        if (top_bit > width) return false;
        w[i / 8] |= x << (4 * (i % 8));
    }
    return true;
}

// Parses the whole batch first; an error string for the first bad command.
static std::string parse(const std::vector<std::string>& t, std::vector<Cmd>& cmds) {
    size_t i = 0;
    while (i < t.size()) {
        Cmd c{};
        const std::string& op = t[i];
        c.op = op.size() == 1 ? op[0] : '?';
        size_t need = 0;
        switch (c.op) {
        case 'W': need = 3; break;
        case 'R': need = 1; break;
        case 'S': need = 2; break;
        case 'C': need = 1; break;
        case 'P': need = 4; break;
        case 'Q': need = 2; break;
        case 'T': need = 0; break;
        default: return "unknown command '" + op + "' (token " + std::to_string(i) + ")";
        }
        if (i + need >= t.size())
            return "command " + op + " at token " + std::to_string(i) + " needs " +
                   std::to_string(need) + " arguments";
        c.text = op;
        for (size_t j = 1; j <= need; j++) c.text += " " + t[i + j];
        bool ok = true;
        switch (c.op) {
        case 'W':
            ok = parse_hex(t[i + 1], c.a, 8) && parse_hex(t[i + 2], c.b, 8) &&
                 parse_hex(t[i + 3], c.c, 1);
            break;
        case 'R': ok = parse_hex(t[i + 1], c.a, 8); break;
        case 'S':
            ok = parse_dec(t[i + 1], c.a) && c.a < (uint64_t)N_STREAMS &&
                 parse_words(t[i + 2], STREAM_WIDTH[c.a], c.words);
            break;
        case 'C': ok = parse_dec(t[i + 1], c.a); break;
        case 'P':
            ok = parse_hex(t[i + 1], c.a, 8) && parse_hex(t[i + 2], c.b, 8) &&
                 parse_hex(t[i + 3], c.c, 8) && parse_dec(t[i + 4], c.d);
            break;
        case 'Q': ok = parse_dec(t[i + 1], c.a) && c.a < (uint64_t)N_WATCH &&
                       parse_dec(t[i + 2], c.b); break;
        default: break;
        }
        if (!ok) return "bad arguments in '" + c.text + "'";
        cmds.push_back(c);
        i += need + 1;
    }
    return "";
}

static bool run(const Cmd& c, std::string& ans, std::string& err) {
    switch (c.op) {
    case 'W': {
        int resp;
        if (!axi_write(c.a, c.b, c.c, resp, err)) return false;
        ans = std::to_string(resp);
        return true;
    }
    case 'R': {
        uint32_t d; int resp;
        if (!axi_read(c.a, d, resp, err)) return false;
        ans = hex(d);
        if (resp) ans += "/" + std::to_string(resp);
        return true;
    }
    case 'S':
        if (!push((int)c.a, c.words.data(), err)) return false;
        ans = ".";
        return true;
    case 'C':
        idle();
        for (uint64_t n = 0; n < c.a; n++) { settle(); edge(); }
        ans = ".";
        return true;
    case 'P': {
        long start = total;
        while (true) {
            uint32_t d; int resp;
            if (!axi_read(c.a, d, resp, err)) return false;
            if (resp) {
                err = "poll of 0x" + hex(c.a) + " answered rresp " + std::to_string(resp);
                return false;
            }
            if ((d & c.b) == c.c) { ans = hex(d); return true; }
            if (total - start >= (long)c.d) {
                err = "poll of 0x" + hex(c.a) + " timed out after " +
                      std::to_string(total - start) + " cycles: rdata 0x" + hex(d) +
                      " & mask 0x" + hex(c.b) + " != 0x" + hex(c.c);
                return false;
            }
        }
    }
    case 'Q': {
        idle();
        long start = total;
        while (true) {
            settle();
            if (watched((int)c.a)) { ans = std::to_string(total - start); return true; }
            if (total - start >= (long)c.b) {
                err = "wait for output " + std::to_string(c.a) + " timed out: low for " +
                      std::to_string(c.b) + " cycles";
                return false;
            }
            edge();
        }
    }
    case 'T':
        ans = std::to_string(total);
        return true;
    }
    err = "internal: unknown command";
    return false;
}

int main(int argc, char** argv) {
    for (int i = 1; i + 1 < argc; i += 2) {
        std::string k = argv[i];
        if (k == "--limit") limit = atol(argv[i + 1]);
        else if (k == "--seed")
            rng = strtoull(argv[i + 1], nullptr, 10) * 0x9E3779B97F4A7C15ull + 1;
        else if (k == "--delay-p") delay_p = atof(argv[i + 1]);
        else if (k == "--max-delay") max_delay = atoi(argv[i + 1]);
        else if (k == "--skew") skew = atoi(argv[i + 1]);
        else { std::cerr << "unknown option " << k << "\n"; return 2; }
    }
    std::ios::sync_with_stdio(false);
    top = new V@TOP@;
    idle();
    top->clk = 0; top->rst = 1;
    for (int i = 0; i < 2; i++) { top->clk = 0; top->eval(); top->clk = 1; top->eval(); }
    top->rst = 0;
    std::string line;
    while (std::getline(std::cin, line)) {
        if (line == "quit") break;
        std::vector<std::string> toks;
        std::istringstream ss(line);
        std::string t;
        while (ss >> t) toks.push_back(t);
        if (!wedged.empty()) {
            std::cout << "!wedged by an earlier timeout: " << wedged << '\n' << std::flush;
            continue;
        }
        std::vector<Cmd> cmds;
        std::string perr = parse(toks, cmds);
        if (!perr.empty()) {
            std::cout << "!malformed batch: " << perr << '\n' << std::flush;
            continue;
        }
        std::string out, ans, err;
        bool failed = false;
        for (size_t i = 0; i < cmds.size(); i++) {
            if (!run(cmds[i], ans, err)) {
                std::cout << "!command " << i << " (" << cmds[i].text << "): " << err
                          << '\n' << std::flush;
                failed = true;
                break;
            }
            if (i) out += ' ';
            out += ans;
        }
        if (!failed) std::cout << out << '\n' << std::flush;
    }
    std::cerr << "cycles " << total << "\n";
    delete top;
    return 0;
}
