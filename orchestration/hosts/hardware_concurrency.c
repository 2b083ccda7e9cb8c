/* Preloaded into a libcosim child process (mast.hosts.cosim.run_host, worker_threads): the number of hardware
 * threads C++ reports, std::thread::hardware_concurrency(), read from MAST_HARDWARE_CONCURRENCY.
 *
 * libcosim's fixed-step algorithm steps the simulators in a pool of worker threads whose size is
 * hardware_concurrency() - 1 (its C API, which libcosimpy calls, has no other way to choose it); on a 2-core
 * machine that is one worker. With this library preloaded the pool has MAST_HARDWARE_CONCURRENCY - 1 workers,
 * so a test compares libcosim stepping the FMUs in several threads with one.
 */
#include <stdlib.h>

unsigned int _ZNSt6thread20hardware_concurrencyEv(void);   /* std::thread::hardware_concurrency() */

unsigned int _ZNSt6thread20hardware_concurrencyEv(void)
{
    const char *value = getenv("MAST_HARDWARE_CONCURRENCY");
    unsigned long n = value ? strtoul(value, NULL, 10) : 0;
    return n ? (unsigned int)n : 1u;
}
