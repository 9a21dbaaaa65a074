"""A day at the station: the capacity model's passes emulated and sent to a front end on a
clock, archived and catalogued, their orders processed by a pool of workers
(``station day``)."""
