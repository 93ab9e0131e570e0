#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>
#include "V%(top)s.h"
#include "verilated.h"

static const int IN_WORDS = %(in_words)d;

static void set_words(uint32_t* dst, const std::string& hex) {
    for (int k = 0; k < IN_WORDS; k++) dst[k] = 0;
    int n = hex.size();
    for (int i = 0; i < n && i / 8 < IN_WORDS; i++) {
        char c = hex[n - 1 - i];
        uint32_t v = (c <= '9') ? c - '0' : (c | 0x20) - 'a' + 10;
        dst[i / 8] |= v << (4 * (i %% 8));
    }
}

int main(int argc, char** argv) {
    long limit = argc > 1 ? atol(argv[1]) : 100000;
    std::ios::sync_with_stdio(false);
    V%(top)s* top = new V%(top)s;
    uint32_t in[IN_WORDS + 1];
    char hexbuf[64];
    top->clk = 0; top->rst = 1; top->i___05Fvalid = 0; top->o___05Fready = 1;
    for (int i = 0; i < 2; i++) { top->clk = 0; top->eval(); top->clk = 1; top->eval(); }
    top->rst = 0;
    long total = 0;
    std::string line;
    while (std::getline(std::cin, line)) {
        if (line == "quit") break;
        std::vector<std::string> toks;
        std::istringstream ss(line);
        std::string t;
        while (ss >> t) toks.push_back(t);
        size_t n = toks.size(), k = 0, outs = 0;
        long idle = 0;
        std::string resp;
        bool failed = false;
        if (n > 0) { set_words(in, toks[0]); top->i___05Fvalid = 1; }
        while (outs < n) {
%(set_payload)s
            top->clk = 0; top->eval();
            bool fire_in = top->i___05Fvalid && top->i___05Fready;
            if (top->o___05Fvalid) {
%(get_payload)s
                if (outs) resp += ' ';
                resp += hexbuf;
                outs++; idle = 0;
            }
            top->clk = 1; top->eval();
            total++; idle++;
            if (fire_in) {
                k++;
                if (k < n) set_words(in, toks[k]); else top->i___05Fvalid = 0;
            }
            if (idle > limit) { failed = true; break; }
        }
        if (failed) {
            top->i___05Fvalid = 0;
            std::cout << "!no output for " << limit << " cycles after " << outs
                      << " of " << n << " commands\n" << std::flush;
            continue;
        }
        std::cout << resp << '\n' << std::flush;
    }
    std::cerr << "cycles " << total << "\n";
    delete top;
    return 0;
}
