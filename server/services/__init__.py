"""Service functions: the work behind the routers, each in one transaction of the Store."""
